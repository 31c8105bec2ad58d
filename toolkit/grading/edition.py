"""Which edition of the course this copy of the toolkit is.

`python -m toolkit course export` (export.py) writes the student edition, whose cl/ holds the
students' own files in place of the reference solutions. It marks that copy in one line: the
Sources that builds use by default (toolkit/opencl/program.py DEFAULT_SOURCES) is, there,
stubs.CourseSources, which refuses an untouched assignment stub. That line is the edition."""
from toolkit.opencl import program

# What the student edition's program.DEFAULT_SOURCES says.
STUDENT_SOURCES = "toolkit.grading.stubs:CourseSources"


def student():
    """Whether this copy is the course's student edition (cl/ holds no reference solution)."""
    return program.DEFAULT_SOURCES == STUDENT_SOURCES


def mark_student(program_file):
    """Make the copy of toolkit/opencl/program.py at `program_file` the student edition's."""
    text = program_file.read_text()
    line = f'DEFAULT_SOURCES = "{program.DEFAULT_SOURCES}"'
    if line not in text:
        raise ValueError(f"{program_file} has no line `{line}` to mark the student edition with")
    program_file.write_text(text.replace(line, f'DEFAULT_SOURCES = "{STUDENT_SOURCES}"'))
