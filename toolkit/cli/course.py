"""`python -m toolkit course export DIR [--instructor]`: the course's student edition (stubs, not
solutions) or instructor edition, written from this checkout (toolkit/grading/export.py says
what each holds)."""
from toolkit.cli.options import DEVICE
from toolkit.grading.export import export


def add_command(sub):
    p = sub.add_parser("course", help="the course: export its student or instructor edition",
                       parents=[DEVICE])
    actions = p.add_subparsers(dest="action", required=True)
    e = actions.add_parser("export", help="write the student edition (or --instructor's) into a new folder",
                           description="The student edition: the toolkit with each assignment's stub in place of "
                                       "its solution, notebooks with exercises in place of solution cells, the "
                                       "handouts, the public checks and a README for students. The instructor "
                                       "edition adds the solutions, the fixtures and the instructor guide.")
    e.add_argument("dir", metavar="DIR", help="a folder that does not exist or is empty")
    e.add_argument("--instructor", action="store_true", help="the instructor edition")
    p.set_defaults(run=cmd_course)


def cmd_course(args):
    files = export(args.dir, instructor=args.instructor)
    print(f"wrote the {'instructor' if args.instructor else 'student'} edition to {args.dir} ({len(files)} files)")
    return 0
