"""The autograder of the course assignments (tutorials/assignments/; see its README.md).

    python -m toolkit grade ASSIGNMENT --stub > mine.cl           # the student's starting point
    python -m toolkit grade ASSIGNMENT --kernel mine.cl [--json]  # grade a submission (or several)
    python -m toolkit grade ASSIGNMENT --solution                 # grade the toolkit's own kernel
    python -m toolkit grade ASSIGNMENT --kernel mine.cl --only scan,parallel   # some checks only

A submission is copied into a fresh folder under the name of the toolkit file it replaces
(`compact.h`, `bdpt_parallel_connect.cl`, `mis.h`, `pt_inplace_regen.cl`) and built in its place:
program.build looks includes up in that folder first, then in cl/ (a technique is given the same
Sources: Context.technique). The toolkit itself is never edited. The student's file may include only
what sources.py allows: the toolkit headers its assignment lists, by a plain name.

The checks of one submission run in one worker subprocess, under limits (limits.py), which
reports them one by one to the grader on a pipe of its own (channel.py: a kernel's printf cannot
write there); each check has a time limit. A check that hangs past it, or crashes the worker,
loses its points with the reason ("stopped after 30 s", "the check crashed
(SIGSEGV)"), the worker is killed and a fresh one goes on with the remaining checks. A kernel
that does not build loses every check, with the compiler's first error at a line of the
student's file. Builds are cached in the worker and on disk (pyopencl's binary cache, PoCL's
kernel cache), so a program is compiled once per submission, and a fresh worker reuses it.
Sharing a process has one risk: a kernel that writes out of bounds can corrupt the worker's memory
and make a later check fail in the host code. So the checks of one piece run before the checks of
the whole file (Assignment.run_first), and a check that fails with a host exception after other
checks ran in its worker is run again in a fresh one.

If the grader itself fails on a file (its worker does not start, or sends what is not a report),
the result says so ("error") and the checks it did not grade earn 0; a batch goes on.

Where it is: this file grades one file; runner.py runs the worker (worker.py) and enforces the
limits (limits.py); channel.py is how the worker reports, sources.py what a submission may
include; checks/<assignment>.py holds each assignment's checks (assignment.py: what a check is;
context.py: what it works with); report.py formats the result; toolkit/cli/grade.py is the command.
"""
import os
import shutil
import tempfile
import time
from pathlib import Path

from toolkit.grading.assignment import NEEDS_REFERENCE, SKIPPED, assignments_dir
from toolkit.grading.checks import ASSIGNMENTS
from toolkit.grading.limits import check_time_limit, stop_on_signals, worker_account
from toolkit.grading.runner import TIME_LIMIT, GraderError, Limits, run_checks
from toolkit.opencl.program import MAX_SOURCE_SIZE, cl_dir

__all__ = ["ASSIGNMENTS", "TIME_LIMIT", "Limits", "assignments_dir", "grade"]


def grade(name, kernel=None, solution=False, time_limit=TIME_LIMIT, device=None, limits=Limits(), only=None,
          inputs=0):
    """Grade one file (`kernel`) or the toolkit's own (`solution`) for assignment `name`. Returns
    {"assignment", "file", "score", "max", "seconds", "checks": [{name, points, earned, reason}]},
    and "error" when the grader failed on it (the checks it did not grade earn 0). `only`: the
    names of the checks to run (None: all); the others are left out of the result and the score is
    rescaled from the points of those run, with a note. `inputs`: 0, the checks' public inputs (the
    ones in the student's copy); another number, hidden ones drawn from it (Context.rng)."""
    a = ASSIGNMENTS[name]
    check_time_limit(time_limit)
    only = selected_checks(a, only)
    source = cl_dir() / a.replaces if solution else submission_file(kernel)
    shown = str(source) if not solution else f"the toolkit's {a.replaces}"
    start = time.perf_counter()
    refused = None if solution else _refused(source)
    if refused:
        return _result(a, shown, {"build": refused}, {}, None, time.perf_counter() - start, only)
    order = ["build"] + [n for n in list(a.run_first) + [c.name for c in a.checks if c.name not in a.run_first]
                         if n in only]
    error = None
    with stop_on_signals(), tempfile.TemporaryDirectory(prefix="grade-") as root:
        folder, workdir = Path(root) / "submission", Path(root) / "worker"
        folder.mkdir()
        workdir.mkdir()
        shutil.copyfile(source, folder / a.replaces)
        for helper in a.helpers:
            shutil.copyfile(a.folder / helper, folder / helper)
        _hand_over(Path(root), folder, workdir, worker_account(limits))
        try:
            reasons, times = run_checks(name, order, folder, time_limit, device, source.name, limits, workdir, inputs)
        except GraderError as failed:
            reasons, times, error = failed.reasons, failed.times, str(failed)
    return _result(a, shown, reasons, times, error, time.perf_counter() - start, only)


def _hand_over(root, folder, workdir, account):
    """Let the worker's user (`account`, if it is not the grader's) into the grading folder `root`,
    and give it the submission's `folder` (a check may build variants of the file beside it: its
    files stay the grader's, readable) and its own `workdir`; nothing else of the grader's."""
    if account is None or account.pw_uid == os.geteuid():
        return
    root.chmod(0o711)   # through, not a listing
    for path in folder.iterdir():
        path.chmod(0o644)
    for owned in (folder, workdir):
        os.chown(owned, account.pw_uid, account.pw_gid)


def selected_checks(a, only):
    """The names in `only` (all of assignment `a`'s checks if None); a ValueError for a name it has not."""
    names = [c.name for c in a.checks]
    if only is None:
        return names
    unknown = [n for n in only if n not in names]
    if unknown or not only:
        raise ValueError(f"{a.name} has no check {', '.join(unknown) or '(none given)'}: its checks are "
                         f"{', '.join(names)}")
    return [n for n in names if n in only]


def submission_file(kernel):
    """The path of a student's file; a ValueError if there is no such file."""
    path = Path(kernel)
    if not path.is_file():
        raise ValueError(f"no such kernel file: {path}")
    return path


def _refused(path):
    """Why a student's file is not built at all, or None: more than MAX_SOURCE_SIZE bytes, or a
    symbolic link to a file in another folder (another student's, or the toolkit's)."""
    if path.is_symlink() and path.resolve().parent != path.absolute().parent.resolve():
        return f"{path.name} is a symbolic link to a file in another folder: submit the file itself"
    if path.stat().st_size > MAX_SOURCE_SIZE:
        return f"{path.name} has {path.stat().st_size:,} bytes, more than the {MAX_SOURCE_SIZE:,} a build may have"
    return None


def _result(a, shown, reasons, times, error, seconds, only=None):
    """The result of grading one file (see grade()) from each check's reason (None: it passed).
    A skipped check (this machine cannot run it) counts neither way: the score is rescaled from
    the points graded to the whole, and "note" says so. Checks not in `only` are left out."""
    problem = reasons.pop("build", None)
    rows = []
    for c in a.checks:
        if only is not None and c.name not in only:
            continue
        if problem:
            reason = f"the kernel does not build: {problem}"
        else:
            reason = reasons[c.name] if c.name in reasons else f"not graded: {error}"
        skipped = bool(reason) and reason.startswith(SKIPPED)
        rows.append({"name": c.name, "points": c.points, "earned": 0 if reason else c.points,
                     "what": c.what, "reason": reason, "hint": None if skipped or not reason else _hint(c, reason),
                     "skipped": skipped, "seconds": round(times.get(c.name, 0.0), 2)})
    whole = sum(c.points for c in a.checks)
    graded = sum(r["points"] for r in rows if not r["skipped"])
    earned = sum(r["earned"] for r in rows)
    result = {"assignment": a.name, "file": shown, "score": round(earned * whole / graded) if graded else 0,
              "max": whole, "seconds": round(seconds, 2), "checks": rows}
    if graded < whole:
        why = []
        if len(rows) < len(a.checks):
            why.append(f"only {', '.join(r['name'] for r in rows)} graded (--only)")
        for reason in dict.fromkeys(r["reason"] for r in rows if r["skipped"]):   # grouped by why, in order
            names = ", ".join(r["name"] for r in rows if r["skipped"] and r["reason"] == reason)
            why.append(f"{names} skipped ({_why_skipped(reason)})")
        result["note"] = (f"{'; '.join(why)}: the score is {earned} of the {graded} points graded, rescaled to "
                          f"{result['score']} of {whole}")
    if error:
        result["error"] = error
    return result


def _why_skipped(reason):
    """A skipped check's reason, short, for the note: what was missing, not how to install it."""
    text = reason[len(SKIPPED):]
    if text == NEEDS_REFERENCE:
        return "it compares with the reference solution: your instructor grades it"
    return text.split(":")[0]   # "this check needs Oclgrind (an OpenCL simulator), which is not installed here"


def _hint(check, reason):
    """What to look at for a lost check: the idea of the check, or what a build error, a hang or
    a crash usually means."""
    if reason.startswith("the kernel does not build"):
        return "fix the compiler's first error; the ones after it often follow from it"
    if reason.startswith("stopped after") or reason.startswith("the build was stopped"):
        return ("a loop whose condition never becomes false, or a barrier inside a branch that not every "
                "work-item of the group takes")
    if reason.startswith("the check crashed") or reason.startswith("the worker"):
        return "an index out of the buffer's range: check each index against the size the buffer has"
    return check.hint
