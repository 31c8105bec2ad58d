"""Which edition of the course this copy of the toolkit is. `python -m toolkit course export`
rewrites this file in the student edition it writes (toolkit/grading/export.py): there, cl/ holds
the students' own files in place of the reference solutions, so the grader must not take cl/'s
files for the reference (toolkit/opencl/stubs.py)."""

STUDENT = False
