"""`python -m toolkit course export DIR [--instructor]`: the course's two editions, from this checkout.

The student edition is a whole working tree, as a course hands out a project skeleton:
  - setup.cfg, pyproject.toml, toolkit/, scenes/, docs/, results/: as they are, so that it installs
    and runs with the toolkit's two commands (README quick start); docs/ without the instructor's
    pages (INSTRUCTOR_ONLY) and the links to them (INSTRUCTOR_REGION);
  - cl/: each assignment's solution file (Assignment.replaces) replaced by its stub, whole (every
    stub is a whole file that builds in the solution's place), so that the techniques which use
    it run on the student's code; a build that reads an untouched stub says which assignment it
    needs (stubs.py): the student edition's builds read cl/ through stubs.CourseSources, the one
    line that marks the edition (edition.py; the grader then never takes cl/'s files for the
    reference solution);
  - tutorials/: the notebooks with the cells tagged "solution" replaced by exercises and no saved
    outputs (notebooks.py); the handouts and the grader's kernels in tutorials/assignments/;
  - tests/: not the toolkit's suite (it asserts the reference solutions' numbers and images, which
    fail on stubs, and holds the wrong-kernel fixtures) but one file: each assignment's public
    checks on the student's cl/ file, skipped while it is still the stub;
  - README.md for students (student_readme below), in place of the toolkit's.
The instructor edition is this checkout as it is (the solutions in cl/, the whole test suite with
tests/fixtures/assignments/, docs/ with the instructor guide, the notebooks with their solution
cells), plus INSTRUCTOR.md: how to export the student edition and grade a class.
"""
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

from toolkit.core.package_data import CHECKOUT
from toolkit.grading import edition, notebooks
from toolkit.grading.checks import ASSIGNMENTS

# Top-level entries of the checkout that the student edition holds (tests/ and README.md are its own).
STUDENT_TOP = ("setup.cfg", "pyproject.toml", ".gitignore", "toolkit", "cl", "scenes", "docs", "results", "tutorials")
# Files of the checkout that only the instructor gets; and, in the docs' pages, the regions between
# these marks (the links to them), which the student edition leaves out.
INSTRUCTOR_ONLY = ("docs/instructor_guide.md", "docs/gradescope.md")
INSTRUCTOR_REGION = re.compile(r"<!-- instructor-only -->.*?<!-- /instructor-only -->\n?", re.S)


def export(target, instructor=False, root=CHECKOUT):
    """Write the student edition (or with `instructor`, the instructor edition) of checkout `root`
    into folder `target`, which must not exist or be empty. Returns the files written (relative)."""
    target = Path(target)
    if target.exists() and (not target.is_dir() or any(target.iterdir())):
        raise ValueError(f"{target} exists and is not an empty folder: give a new folder for the course")
    if not (Path(root) / "setup.cfg").is_file() or not (Path(root) / "tutorials").is_dir():
        raise ValueError(f"course export needs the toolkit's source checkout; {root} is not one")
    if instructor and edition.student():
        raise ValueError("this is the student edition: it holds no solutions to export an instructor edition from")
    files = source_files(root)
    if not instructor:
        files = [f for f in files if f.split("/")[0] in STUDENT_TOP and f not in INSTRUCTOR_ONLY]
    target.mkdir(parents=True, exist_ok=True)
    for name in files:
        _copy(Path(root) / name, target / name)
    if instructor:
        _write(target / "INSTRUCTOR.md", instructor_readme())
        return files + ["INSTRUCTOR.md"]
    written = list(files)
    for a in ASSIGNMENTS.values():   # every stub in its solution's place
        shutil.copyfile(Path(root) / "tutorials/assignments" / a.name / a.stub, target / "cl" / a.replaces)
    edition.mark_student(target / "toolkit/opencl/program.py")
    for name in files:
        if name.startswith("tutorials/") and name.endswith(".ipynb"):
            path = target / name
            path.write_text(json.dumps(notebooks.student_notebook(json.loads(path.read_text())), indent=1,
                                       ensure_ascii=False) + "\n")
    for name in files:
        if name.startswith("docs/") and name.endswith(".md"):
            path = target / name
            path.write_text(INSTRUCTOR_REGION.sub("", path.read_text()))
    _write(target / "README.md", student_readme())
    _write(target / "tests/test_my_assignments.py", STUDENT_TESTS)
    return written + ["README.md", "tests/test_my_assignments.py"]


# The README's parts that the docs' pages include (docs/index.md, docs/getting_started.md): the
# student README has them too, so that the student edition's docs build (tests/test_course_export.py).
README_MARKS = ("PyOpenCL teaching toolkit", "![SIMD efficiency", "## Quick start", "## Documentation")


def source_files(root):
    """The checkout's files: git's tracked and untracked-but-not-ignored ones where it is a git
    work tree (no caches, builds or renders), else every file but those of caches."""
    try:
        out = subprocess.run(["git", "-C", str(root), "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                             capture_output=True, check=True).stdout.decode()
        names = [n for n in out.split("\0") if n]
    except (OSError, subprocess.CalledProcessError):
        names = [str(p.relative_to(root)).replace(os.sep, "/") for p in Path(root).rglob("*") if p.is_file()]
        names = [n for n in names if not any(part in ("__pycache__", ".git", "_build", ".ipynb_checkpoints", "out")
                                             for part in n.split("/"))]
    return sorted(n for n in names if (Path(root) / n).is_file())


def _copy(source, destination):
    destination.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(source, destination)


def _write(path, text):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def student_readme():
    rows = "\n".join(f"| {i} | `{a.name}` | {a.title} | `cl/{a.replaces}` | "
                     f"[handout](tutorials/assignments/{a.name}/README.md) |"
                     for i, a in enumerate(ASSIGNMENTS.values(), start=1))
    return f"""# SIMD-efficient Monte Carlo light transport: the course's PyOpenCL teaching toolkit

This is your copy of the course's toolkit: Python host code and OpenCL kernels that turn
Dietger van Antwerpen's HPG 2011 talk *"Improving SIMD Efficiency for Parallel Monte Carlo
Light Transport on the GPU"* into techniques you can run, measure and extend. Some of its
kernels are yours to write: in `cl/`, each assignment's file is a stub that builds but does
nothing yet. Until you write it, whatever uses it (a technique, a notebook cell) stops with a
message that names the assignment.

![SIMD efficiency per iteration of the three path tracers on the Cornell box](docs/_static/simd_efficiency.png)

## Quick start

```bash
pip install . && python -m toolkit render
pip install ".[test]" && python -m pytest
```

The first command installs the toolkit and renders the bundled Cornell box with the plain path
tracer to `out/cornell_box_pt_naive.exr` and `.png`. The second runs the public checks of each
assignment on your file in `cl/`; an assignment whose file is still the stub is skipped.

## The assignments

| # | name | what | your file | handout |
|---|------|------|-----------|---------|
{rows}

Write your solution in the file in place (run the commands from this folder, so that Python uses
this folder's toolkit and `cl/`), and check it with the grader's public checks:

```bash
python -m toolkit grade compaction --kernel cl/compact.h
```

Each lost point comes with its reason and a hint. Checks that compare your results with the
reference solution are not in your copy: they are skipped here, and your instructor runs them,
with other inputs than the ones you see. `python -m toolkit grade NAME --stub` prints a fresh stub.

## The notebooks

`tutorials/` holds the notebooks that measure each technique (`pip install ".[test]"` installs
Jupyter's kernel; open them with Jupyter or VS Code). Cells that showed a solution are exercises
here; a cell that needs an assignment you have not written says so, and the notebook goes on.
## Documentation

The documentation is built from `docs/`: `pip install ".[docs]"`, then
`python -m sphinx -b html docs docs/_build/html`.
"""


def instructor_readme():
    return """# The course: instructor's notes

This folder is the toolkit with everything the course needs: the reference solutions in `cl/`,
the whole test suite with the wrong-kernel fixtures (`tests/fixtures/assignments/`), the
notebooks with their solution cells, and the documentation with the instructor guide.

- The student edition, to hand out: `python -m toolkit course export DIR` (no solutions,
  fixtures or guide; stubs in `cl/`; exercises in the notebooks).
- A submission: `python -m toolkit grade NAME --kernel FILE` runs every check, the ones that
  compare with the reference solution included (the student edition skips those).
"""


STUDENT_TESTS = '''"""Your assignments, by the grader's public checks: the test of an assignment passes when no
check that ran lost points, and is skipped while its file in cl/ is still the stub. The same
report, with the reason and a hint for each lost point: `python -m toolkit grade NAME --kernel cl/FILE`."""
import pytest

from toolkit.grading.grade import ASSIGNMENTS, grade
from toolkit.grading.report import format_report
from toolkit.opencl.program import cl_dir


@pytest.mark.parametrize("name", list(ASSIGNMENTS))
def test_assignment(name, record_property):
    a = ASSIGNMENTS[name]
    mine = cl_dir() / a.replaces
    if mine.read_text() == (a.folder / a.stub).read_text():
        pytest.skip(f"cl/{a.replaces} is still the stub of {name}")
    result = grade(name, mine)
    # the checks your copy skips because they compare with the reference solution (your instructor runs them)
    record_property("instructor_checks", " ".join(c["name"] for c in result["checks"]
                                                  if c["skipped"] and "reference solution" in c["reason"]))
    lost = [c for c in result["checks"] if c["reason"] and not c["skipped"]]
    assert not lost and "error" not in result, format_report(result)
'''
