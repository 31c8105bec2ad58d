"""`python -m toolkit course export DIR --gradescope`: one Gradescope autograder zip per assignment.

Each DIR/<assignment>.zip holds, at its top (Gradescope unpacks it into /autograder/source/):
  setup.sh         run once, as root, when Gradescope builds the image: Python, gcc and libc6-dev
                   (PoCL links every kernel with the system's linker, against libc), a virtual
                   environment at VENV with the toolkit installed from the wheel beside it (its
                   dependencies from the package index: PoCL, pyopencl, ...), then the reference
                   solution graded once there, which fails the build unless it scores 100 (and
                   leaves the kernel caches warm for the submissions);
  run_autograder   run once per submission: gradescope_run.py grades it into results.json;
  the wheel        this checkout's toolkit, built now (`pip wheel --no-deps`): the reference
                   solutions the hidden checks compare with, never in the students' edition;
  autograder.json  the assignment, the hidden inputs' number (drawn now, the same for every
                   submission; `course grade --inputs N --time-limit 30` grades again offline
                   on the same inputs), who sees the hidden checks (`--hidden-visibility`), the
                   time limit per check (TIME_LIMIT),
                   and the unprivileged user (WORKER_USER, made by setup.sh) the checks run as.
The zip is the instructor's: Gradescope never shows its files to students, and the number is in
no result a student sees.
"""
import json
import shutil
import stat
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

from toolkit.core.images import write_atomically
from toolkit.core.package_data import CHECKOUT
from toolkit.grading import edition
from toolkit.grading.batch import hidden_inputs
from toolkit.grading.checks import ASSIGNMENTS
from toolkit.grading.export import source_files
from toolkit.grading.gradescope_results import check_visibility
from toolkit.grading.gradescope_run import SETTINGS
from toolkit.grading.limits import TIME_LIMIT, check_time_limit

VENV = "/opt/simd-toolkit"   # where setup.sh installs the toolkit in the image
WORKER_USER = "simd-grader"  # the unprivileged account setup.sh makes, that runs the students' kernels
# What the wheel is built from: the files setup.cfg packages, and the files setup.cfg reads.
WHEEL_SOURCES = ("setup.cfg", "pyproject.toml", "README.md", "toolkit/", "cl/", "scenes/", "tutorials/assignments/")

SETUP_SH = """#!/usr/bin/env bash
# Gradescope runs this once, as root, to build the autograder's image (Ubuntu): Python, a
# compiler's linker and libc for PoCL, the toolkit from the wheel beside this file with its
# dependencies from the package index, then the reference solution graded once, which fails
# the build unless it scores 100.
# Written by `python -m toolkit course export DIR --gradescope`.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
export DEBIAN_FRONTEND=noninteractive
# PoCL (pip's) links each kernel with the system's linker against libc and libgcc: gcc and libc6-dev
apt-get update
apt-get install -y --no-install-recommends python3 python3-venv python3-pip ca-certificates gcc libc6-dev
python3 -m venv {venv}
{venv}/bin/pip install --no-cache-dir --upgrade pip
{venv}/bin/pip install --no-cache-dir "$here/{wheel}"
# the students' kernels run as this user (its home keeps their kernel caches), never as root
id -u {user} >/dev/null 2>&1 || useradd --system --create-home --shell /usr/sbin/nologin {user}
# the reference solution, graded as a submission would be: the image works, the caches are warm
{venv}/bin/python -m toolkit.grading.gradescope_run --check-solution "$here"
"""

RUN_AUTOGRADER = """#!/usr/bin/env bash
# Gradescope runs this once per submission: it grades /autograder/submission/ into
# /autograder/results/results.json (toolkit/grading/gradescope_run.py). AUTOGRADER_ROOT, if set,
# stands for /autograder (a test, or a try on your machine: then python3 from PATH runs it).
# Written by `python -m toolkit course export DIR --gradescope`.
if [ -n "${{AUTOGRADER_ROOT:-}}" ]; then
    exec python3 -m toolkit.grading.gradescope_run "$AUTOGRADER_ROOT"
fi
exec {venv}/bin/python -m toolkit.grading.gradescope_run /autograder
"""


def export_gradescope(target, names=None, hidden_visibility="after_due_date", inputs=None, time_limit=TIME_LIMIT,
                      root=CHECKOUT, progress=print):
    """Write one autograder zip per assignment of `names` (all if None) into folder `target`, which
    must not exist or be empty. Returns (the zips written, the hidden inputs' number)."""
    target = Path(target)
    if target.exists() and (not target.is_dir() or any(target.iterdir())):
        raise ValueError(f"{target} exists and is not an empty folder: give a new folder for the autograders")
    if edition.student():
        raise ValueError("this is the student edition: an autograder needs the reference solutions, which it "
                         "lacks; export from the instructor's checkout")
    if not (Path(root) / "setup.cfg").is_file():
        raise ValueError(f"--gradescope needs the toolkit's source checkout, to build its wheel; {root} is not one")
    names = list(ASSIGNMENTS) if names is None else names
    unknown = [n for n in names if n not in ASSIGNMENTS]
    if unknown or not names:
        raise ValueError(f"no assignment {', '.join(unknown) or '(none given)'}: the assignments are "
                         f"{', '.join(ASSIGNMENTS)}")
    check_visibility(hidden_visibility)
    check_time_limit(time_limit)
    inputs = hidden_inputs() if inputs is None else inputs
    if not 0 < inputs < 2**31:
        raise ValueError(f"--inputs must be a number from 1 to {2**31 - 1} (0 would be the public inputs)")
    with tempfile.TemporaryDirectory(prefix="gradescope-wheel-") as scratch:
        progress("building the toolkit's wheel ...")
        wheel = build_wheel(root, Path(scratch))
        zips = []
        for name in names:
            settings = {"assignment": name, "inputs": inputs, "hidden_visibility": hidden_visibility,
                        "time_limit": time_limit, "worker_user": WORKER_USER, "wheel": wheel.name}
            zips.append(write_atomically(target / f"{name}.zip",
                                         lambda tmp, s=settings: _write_zip(tmp, s, wheel)))
    return zips, inputs


def build_wheel(root, scratch):
    """The toolkit's wheel, built by pip from a copy of the checkout's tracked files (so that the
    build leaves nothing in the checkout): without the package index where setuptools and wheel
    are installed, else with it. Returns its path in `scratch`."""
    copy = scratch / "source"
    for name in source_files(root):
        if name.startswith(WHEEL_SOURCES):
            (copy / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(Path(root) / name, copy / name)
    out = scratch / "wheel"
    command = [sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "--wheel-dir", str(out), str(copy)]
    built = subprocess.run(command[:4] + ["--no-build-isolation"] + command[4:], capture_output=True, text=True)
    if built.returncode != 0:   # no setuptools or wheel here: pip fetches them into an isolated build
        built = subprocess.run(command, capture_output=True, text=True)
    wheels = sorted(out.glob("*.whl"))
    if built.returncode != 0 or len(wheels) != 1:
        last = (built.stderr.strip().splitlines() or ["no message"])[-1]
        raise OSError(f"pip could not build the toolkit's wheel ({last}); install setuptools and wheel "
                      "(pip install setuptools wheel) and export again")
    return wheels[0]


def _write_zip(path, settings, wheel):
    scripts = {"setup.sh": SETUP_SH.format(venv=VENV, wheel=wheel.name, user=WORKER_USER),
               "run_autograder": RUN_AUTOGRADER.format(venv=VENV)}
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for name, text in scripts.items():
            info = zipfile.ZipInfo(name, date_time=(2026, 1, 1, 0, 0, 0))
            info.external_attr = (stat.S_IFREG | 0o755) << 16   # executable once unzipped
            info.compress_type = zipfile.ZIP_DEFLATED
            z.writestr(info, text)
        z.writestr(SETTINGS, json.dumps(settings, indent=1) + "\n")
        z.write(wheel, wheel.name)
