"""`python -m toolkit grade`: the autograder of the course assignments (toolkit/grading/grade.py
explains how a submission is graded; tutorials/assignments/README.md is the students' side)."""
import json
import sys

from toolkit.cli.options import DEVICE, number
from toolkit.grading.grade import ASSIGNMENTS, TIME_LIMIT, grade, selected_checks, submission_file
from toolkit.grading.limits import MAX_TIME_LIMIT, check_time_limit
from toolkit.grading.report import format_report


def add_command(sub):
    p = sub.add_parser("grade", help="grade a course assignment (tutorials/assignments/): score /100 per check",
                       parents=[DEVICE])
    p.add_argument("assignment", choices=list(ASSIGNMENTS))
    p.add_argument("--kernel", nargs="+", metavar="PATH", help="your file(s), built in place of the toolkit's")
    p.add_argument("--solution", action="store_true", help="grade the toolkit's own kernel (the reference solution)")
    p.add_argument("--stub", action="store_true", help="print the assignment's starting file")
    p.add_argument("--json", action="store_true", help="one JSON line per graded file")
    p.add_argument("--time-limit", type=number, default=TIME_LIMIT, metavar="SECONDS",
                   help=f"per check (default {TIME_LIMIT}, at most {MAX_TIME_LIMIT}); a kernel that runs "
                        "longer loses the check")
    p.add_argument("--only", type=check_names, metavar="CHECK,...",
                   help="run only these checks (e.g. to grade again what a fix should change); the score is "
                        "rescaled from their points")
    p.set_defaults(run=cmd_grade)


def check_names(text):
    """'scan,parallel' -> ['scan', 'parallel'] (grade() says which names an assignment has)."""
    return [n.strip() for n in text.split(",") if n.strip()]


def cmd_grade(args):
    """--stub prints the student's starting file; otherwise every file given is graded, in order.
    Exit status 1 if the grader failed on some file (each is graded all the same), 2 for bad input."""
    a = ASSIGNMENTS[args.assignment]
    if args.stub:
        sys.stdout.write((a.folder / a.stub).read_text())
        return 0
    if not args.solution and not args.kernel:
        raise ValueError(f"give --kernel PATH (your file; start from `python -m toolkit grade {a.name} --stub`) "
                         "or --solution")
    check_time_limit(args.time_limit)
    selected_checks(a, args.only)   # a wrong name is refused before any file is graded
    files = [None] if args.solution else args.kernel
    for path in files:
        if path is not None:
            submission_file(path)   # every file is checked before the first is graded
    failed = False
    for path in files:
        result = grade(a.name, path, solution=args.solution, time_limit=args.time_limit, device=args.device,
                       only=args.only)
        print(json.dumps(result) if args.json else format_report(result), flush=True)
        failed = failed or "error" in result
    if failed:   # the grader's own failure on some file (its report says which): grade those again
        print("error: the grader failed on some files; their reports say why", file=sys.stderr)
    return 1 if failed else 0
