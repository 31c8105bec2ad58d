"""An assignment's stub in the place of a toolkit file: the course's student edition.

`python -m toolkit course export` writes a student edition whose cl/ holds each assignment's
stub (tutorials/assignments/<name>/*_stub.cl) in place of the toolkit file that is its solution.
A stub builds, but does nothing (a scan that returns 0, weights of 0): a technique built from it
would render black or wrong without a word. So CourseSources, the Sources every build of the
student edition reads its files through (edition.py), raises AssignmentNotWritten for a cl/ file
which is still, byte for byte, an untouched stub; the notebooks of the student edition print that
message and go on (notebooks.py). The renderer (toolkit/opencl/program.py) knows nothing of this:
it reads its files through whichever Sources it is given.

The grader refuses the stub of its own assignment's file only (`refused`, context.py): the stubs
of the other assignments then build as they are. In the student edition the graded file in cl/ is
the student's own, not the reference solution, whether written or not: a check that compares
with the reference is refused it (ReferenceMissing) and skipped."""
from functools import lru_cache

from toolkit.core.package_data import data_dir
from toolkit.grading import edition
from toolkit.opencl.program import Sources, cl_dir


class AssignmentNotWritten(RuntimeError):
    """A build read a cl/ file that is still the untouched stub of a course assignment."""

    def __init__(self, file, assignment):
        super().__init__(f"cl/{file} is still the stub of assignment `{assignment}`: this needs your solution "
                         f"(tutorials/assignments/{assignment}/README.md; check it with `python -m toolkit grade "
                         f"{assignment} --kernel cl/{file}`)")
        self.file, self.assignment = file, assignment


class ReferenceMissing(AssignmentNotWritten):
    """The grader of the student edition asked for the reference solution, which it does not hold."""

    def __init__(self, file):
        RuntimeError.__init__(self, f"the reference solution of cl/{file} is not in the student edition")
        self.file, self.assignment = file, None


@lru_cache(maxsize=1)
def stub_texts():
    """{stub text: assignment name} of every stub in tutorials/assignments/*/."""
    folder = data_dir("toolkit.assignments", "tutorials/assignments", "README.md")
    return {path.read_text(): path.parent.name for path in sorted(folder.glob("*/*_stub.cl"))}


class CourseSources(Sources):
    """program.Sources that refuses a file of cl/ which is still an untouched assignment stub.
    `refused`: the cl/ file names whose stub is refused (None: every one). Costs one comparison
    per file read."""

    def __init__(self, folder=None, refused=None):
        super().__init__(folder)
        self.refused = None if refused is None else frozenset(refused)

    def toolkit_only(self):
        return CourseSources(refused=self.refused)

    def read(self, path):
        text = super().read(path)
        if path.parent == cl_dir():   # the toolkit's own file, not one of `folder`
            self.check_written(path.name, text)
        return text

    def check_written(self, name, text):
        """Raise AssignmentNotWritten if `text`, read from cl/`name`, is an untouched stub (and refused)."""
        if self.refused is not None:
            if name not in self.refused:
                return
            if edition.student():
                raise ReferenceMissing(name)
        assignment = stub_texts().get(text)
        if assignment is not None:
            raise AssignmentNotWritten(name, assignment)
