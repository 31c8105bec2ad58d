"""The autograder of the course assignments (tutorials/assignments/; see its README.md).

    python -m toolkit grade ASSIGNMENT --stub > mine.cl           # the student's starting point
    python -m toolkit grade ASSIGNMENT --kernel mine.cl [--json]  # grade a submission (or several)
    python -m toolkit grade ASSIGNMENT --solution                 # grade the toolkit's own kernel

A submission is copied into a fresh folder under the name of the toolkit file it replaces
(`compact.h`, `bdpt_parallel_connect.cl`, `mis.h`, `pt_inplace_regen.cl`) and built in its place:
program.build looks includes up in that folder first, then in cl/ (Technique.source_dir does the
same for a technique). The toolkit itself is never edited.

The checks of one submission run in one worker subprocess, which reports them one by one (a line
of JSON each) to the grader; each check has a time limit. A check that hangs past it, or crashes
the worker, loses its points with the reason ("stopped after 30 s", "the check crashed
(SIGSEGV)"), the worker is killed and a fresh one goes on with the remaining checks. A kernel
that does not build loses every check, with the compiler's first error at a line of the
student's file. Builds are cached in the worker and on disk (pyopencl's binary cache, PoCL's
kernel cache), so a program is compiled once per submission, and a fresh worker reuses it.
Sharing a process has one risk: a kernel that writes out of bounds can corrupt the worker's memory
and make a later check fail in the host code. So the checks of one piece run before the checks of
the whole file (Assignment.run_first), and a check that fails with a host exception after other
checks ran in its worker is run again in a fresh one.

Where it is: this file grades one file; runner.py runs the worker (worker.py) and enforces the
limits; checks/<assignment>.py holds each assignment's checks (assignment.py: what a check is;
context.py: what it works with); report.py formats the result; toolkit/cli/grade.py is the command.
"""
import shutil
import tempfile
import time
from pathlib import Path

from toolkit.grading.assignment import assignments_dir
from toolkit.grading.checks import ASSIGNMENTS
from toolkit.grading.runner import TIME_LIMIT, run_checks
from toolkit.opencl.program import cl_dir

__all__ = ["ASSIGNMENTS", "TIME_LIMIT", "assignments_dir", "grade"]


def grade(name, kernel=None, solution=False, time_limit=TIME_LIMIT, device=None):
    """Grade one file (`kernel`) or the toolkit's own (`solution`) for assignment `name`.
    Returns {"assignment", "file", "score", "max", "seconds", "checks": [{name, points, earned, reason}]}."""
    a = ASSIGNMENTS[name]
    source = cl_dir() / a.replaces if solution else Path(kernel)
    if not source.is_file():
        raise ValueError(f"no such kernel file: {source}")
    shown = str(source) if not solution else f"the toolkit's {a.replaces}"
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="grade-") as folder:
        shutil.copyfile(source, Path(folder) / a.replaces)
        for helper in a.helpers:
            shutil.copyfile(a.folder / helper, Path(folder) / helper)
        order = list(a.run_first) + [c.name for c in a.checks if c.name not in a.run_first]
        reasons, times = run_checks(name, ["build"] + order, folder, time_limit, device, source.name)
    problem = reasons.pop("build")
    rows = []
    for c in a.checks:
        reason = f"the kernel does not build: {problem}" if problem else reasons[c.name]
        rows.append({"name": c.name, "points": c.points, "earned": 0 if reason else c.points,
                     "what": c.what, "reason": reason, "seconds": round(times.get(c.name, 0.0), 2)})
    return {"assignment": name, "file": shown, "score": sum(r["earned"] for r in rows),
            "max": sum(r["points"] for r in rows), "seconds": round(time.perf_counter() - start, 2),
            "checks": rows}
