"""What an assignment is to the grader: the toolkit file a submission replaces, the student's stub
(in tutorials/assignments/<name>/), the grader's own kernels beside it, the toolkit headers a
submission may include, and its checks, each worth points. A check is a function of a Context
(context.py) that raises CheckFailed to lose them."""
from dataclasses import dataclass, field

import numpy as np

from toolkit.core.package_data import data_dir


def assignments_dir():
    """The folder of the assignments (installed data package toolkit.assignments, or the checkout)."""
    return data_dir("toolkit.assignments", "tutorials/assignments", "README.md")


class CheckFailed(Exception):
    """A check's one-line reason for losing its points."""


# A skipped check's reason starts with this (the worker writes it; only the grader's code raises
# CheckSkipped): it is left out of the score, which is rescaled to the points graded (grade.py).
SKIPPED = "skipped: "
# Why a check of the student edition is skipped when it compares with the reference solution
# (the stub is in its place there: worker.py)
NEEDS_REFERENCE = ("it compares with the reference solution, which this edition of the course does not hold: "
                   "your instructor grades it")


class CheckSkipped(Exception):
    """This machine cannot run the check (a tool it needs is missing): it earns no points and
    costs none."""


@dataclass
class Check:
    name: str
    points: int
    what: str
    run: object
    hint: str = ""   # the idea a student who lost these points should look at (not the line)
    # A hidden check compares with the reference solution: the student edition, which lacks it,
    # skips the check (worker.py), so only the instructor's grader runs it. The others are public.
    hidden: bool = False


@dataclass
class Assignment:
    name: str
    title: str
    replaces: str          # the toolkit file (in cl/) that a submission is built in place of
    stub: str              # the student's starting file, in tutorials/assignments/<name>/
    helpers: tuple = ()    # grader kernels in that folder, copied beside the submission
    run_first: tuple = ()  # checks that run before the others (the report keeps the checks' order)
    headers: tuple = ()    # the toolkit's cl/ headers that a submission may include (sources.py)
    checks: list = field(default_factory=list)
    build: object = None   # the "build" step: builds what every check builds (see builds())

    @property
    def folder(self):
        return assignments_dir() / self.name

    def check(self, name, points, what, hint, hidden=False):
        """Decorator: the function is check `name`, worth `points`; `what` is its line in the report,
        `hint` the idea behind it, shown when its points are lost; `hidden`: it compares with the
        reference solution (see Check). The report lists the checks in the order they are declared."""
        def register(function):
            self.checks.append(Check(name, points, what, function, hint, hidden))
            return function
        return register

    def builds(self, function):
        """Decorator: the function builds everything the checks build, the student's programs and the
        toolkit's reference ones. The build step has Limits.build seconds (a cold compiler cache), a
        check only its time limit (limits.py)."""
        self.build = function
        return function


def same_image(image, expected, whom, rtol=1e-5, atol=1e-7):
    """Raise CheckFailed, naming the first pixel, unless `image` equals `expected` (from `whom`)."""
    if image.shape != expected.shape:
        raise CheckFailed(f"the image is {image.shape}, {whom} gives {expected.shape}")
    close = np.isclose(image, expected, rtol=rtol, atol=atol).all(-1)
    if not close.all():
        y, x = np.argwhere(~close)[0]
        raise CheckFailed(f"the image differs from {whom} in {int((~close).sum())} of {close.size} pixels; first at "
                          f"(x={x}, y={y}): {np.round(image[y, x], 5).tolist()} instead of "
                          f"{np.round(expected[y, x], 5).tolist()}")
