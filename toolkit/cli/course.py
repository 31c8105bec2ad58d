"""`python -m toolkit course`: the course's two editions, and grading a class.

    python -m toolkit course export DIR [--instructor]   # toolkit/grading/export.py says what each holds
    python -m toolkit course export DIR --gradescope     # an autograder zip per assignment (gradescope_export.py)
    python -m toolkit course grade SUBMISSIONS --out DIR # toolkit/grading/batch.py: grades.csv, reports/
"""
import sys

from toolkit.cli.grade import check_names
from toolkit.cli.options import DEVICE, number
from toolkit.grading.batch import grade_class
from toolkit.grading.export import export
from toolkit.grading.gradescope_export import TIME_LIMIT as GRADESCOPE_TIME_LIMIT, export_gradescope
from toolkit.grading.gradescope_results import VISIBILITIES
from toolkit.grading.limits import MAX_TIME_LIMIT, check_time_limit
from toolkit.grading.runner import TIME_LIMIT


def add_command(sub):
    p = sub.add_parser("course", help="the course: export its student or instructor edition, grade a class",
                       parents=[DEVICE])
    actions = p.add_subparsers(dest="action", required=True)
    e = actions.add_parser("export", help="write the student edition (or --instructor's) into a new folder",
                           description="The student edition: the toolkit with each assignment's stub in place of "
                                       "its solution, notebooks with exercises in place of solution cells, the "
                                       "handouts, the public checks and a README for students. The instructor "
                                       "edition adds the solutions, the fixtures and the instructor guide.")
    e.add_argument("dir", metavar="DIR", help="a folder that does not exist or is empty")
    e.add_argument("--instructor", action="store_true", help="the instructor edition")
    e.add_argument("--gradescope", action="store_true",
                   help="instead, one Gradescope autograder zip per assignment (docs: the instructor guide)")
    e.add_argument("--assignments", type=check_names, metavar="NAME,...",
                   help="--gradescope: only these (default: all)")
    e.add_argument("--hidden-visibility", choices=VISIBILITIES, default="after_due_date",
                   help="--gradescope: when students see the checks that compare with the reference solution "
                        "(Gradescope's visibility; the public checks are visible at once; default after_due_date)")
    e.add_argument("--inputs", type=int, metavar="N", help="--gradescope: the hidden inputs' number (default: a new "
                   "one, printed; `course grade --inputs N` grades again offline on the same inputs)")
    e.add_argument("--time-limit", type=number, metavar="SECONDS",
                   help=f"--gradescope: per check (default {GRADESCOPE_TIME_LIMIT}, at most {MAX_TIME_LIMIT})")
    g = actions.add_parser("grade", help="grade a folder of submissions (one folder per student) with every check",
                           description="Each student's folder holds their files by the names of the toolkit files "
                                       "they replace, in cl/ (as in the student edition) or at its top. Writes "
                                       "DIR/grades.csv (a row per student) and DIR/reports/<student>.txt.")
    g.add_argument("submissions", metavar="SUBMISSIONS", help="a folder with one folder per student")
    g.add_argument("--out", required=True, metavar="DIR", help="where grades.csv and reports/ are written")
    g.add_argument("--assignments", type=check_names, metavar="NAME,...", help="only these (default: all)")
    g.add_argument("--time-limit", type=number, default=TIME_LIMIT, metavar="SECONDS",
                   help=f"per check (default {TIME_LIMIT}, at most {MAX_TIME_LIMIT})")
    g.add_argument("--inputs", type=int, metavar="N", help="the hidden inputs' number (default: a new one; "
                   "the one grades.csv gives grades again on the same inputs)")
    p.set_defaults(run=cmd_course)


def cmd_course(args):
    if args.action == "grade":
        check_time_limit(args.time_limit)
        grades, inputs = grade_class(args.submissions, args.out, args.assignments, args.time_limit, args.device,
                                     progress=lambda line: print(line, file=sys.stderr, flush=True),
                                     inputs=args.inputs)
        failed = any("error" in r for results in grades.values() for r in results.values())
        print(f"graded {len(grades)} students on hidden inputs {inputs}: {args.out}/grades.csv, reports in "
              f"{args.out}/reports/")
        return 1 if failed else 0
    if args.gradescope:
        if args.instructor:
            raise ValueError("--gradescope writes autograders, not an edition: give it without --instructor")
        limit = GRADESCOPE_TIME_LIMIT if args.time_limit is None else args.time_limit
        zips, inputs = export_gradescope(args.dir, args.assignments, args.hidden_visibility, args.inputs, limit,
                                         progress=lambda line: print(line, file=sys.stderr))
        print(f"wrote {len(zips)} Gradescope autograders to {args.dir}: {', '.join(z.name for z in zips)}; hidden "
              f"inputs {inputs} (keep it to grade again offline: course grade SUBMISSIONS --inputs {inputs} "
              f"--time-limit {limit:g})")
        return 0
    if args.assignments or args.inputs is not None or args.time_limit is not None:
        raise ValueError("--assignments, --inputs and --time-limit choose what --gradescope exports: give them with "
                         "--gradescope")
    files = export(args.dir, instructor=args.instructor)
    print(f"wrote the {'instructor' if args.instructor else 'student'} edition to {args.dir} ({len(files)} files)")
    return 0
