"""The grader's side of the worker subprocess (worker.py runs the checks): start a worker, read
its reports, enforce the time limits, and after a hang or a crash, a fresh worker for the checks
that remain. Nothing here runs a kernel: a student's kernel cannot hang or crash the grader."""
import json
import os
import selectors
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from toolkit.opencl.device import NoOpenCLError

TIME_LIMIT = 10     # seconds per check (a check takes 0.1-3 s on a 2-core CPU): a loop that never
                    # ends in one function costs the few checks that call it, well within a minute
STARTUP_LIMIT = 60  # seconds for a worker to start (Python, numpy, pyopencl, the OpenCL queue)
BUILD_LIMIT = 180   # seconds to build a submission's programs (a cold compiler cache; nothing runs yet)
# The folder holding toolkit/ (the checkout, or site-packages): the worker runs this same toolkit.
TOOLKIT_PARENT = Path(__file__).resolve().parents[2]


def run_checks(name, pending, folder, time_limit, device, shown):
    """Run the checks `pending` (the first is "build") in one worker subprocess, which reports each
    check as one JSON line on its stdout. A check that runs past `time_limit` or crashes the worker
    gets its reason, the worker is killed, and a fresh one goes on with the remaining checks.
    A failed build stops the grading: every check then loses its points for that reason.
    Returns {check name: None if it passed, else its one-line reason}, {check name: seconds}."""
    reasons, times = {}, {}
    pending = list(pending)
    while pending:
        # a fresh worker after a hang or crash builds first too (from the caches, under BUILD_LIMIT)
        session = list(pending) if pending[0] == "build" else ["build"] + pending
        for check_name, reason, seconds in _worker_session(name, session, folder, time_limit, device, shown):
            if check_name == "build" and "build" in reasons:
                if reason:   # it built before: the rebuild was stopped or crashed; the next check pays
                    reasons[pending[0]], times[pending[0]] = reason, seconds
                    pending.pop(0)
                continue
            reasons[check_name] = reason
            times[check_name] = seconds
            pending.remove(check_name)
            if check_name == "build" and reason:
                return dict(reasons, **{p: None for p in pending}), times
    return reasons, times


def _worker_session(name, pending, folder, time_limit, device, shown):
    """One worker process: yields (check, reason, seconds) as the checks finish; the last one it
    yields is the check it was stopped or crashed in (if any), and then it is gone. Start-up (Python,
    the OpenCL queue) has STARTUP_LIMIT seconds, the build BUILD_LIMIT (a compiler does not hang, but
    is slow with a cold cache); each check's time limit starts when it starts."""
    command = [sys.executable, "-m", "toolkit.grading.worker", name, folder, shown, device or "", *pending]
    env = dict(os.environ)
    env["PYTHONPATH"] = str(TOOLKIT_PARENT) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    with tempfile.TemporaryFile("w+") as errors:
        worker = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=errors, env=env, start_new_session=True)
        selector = selectors.DefaultSelector()
        selector.register(worker.stdout, selectors.EVENT_READ)
        current, buffer, announced = pending[0], b"", False
        started = time.monotonic()
        deadline = started + max(time_limit, STARTUP_LIMIT)
        try:
            while True:
                left = deadline - time.monotonic()
                if left <= 0 or not selector.select(timeout=left):
                    _kill(worker)
                    if not announced:
                        raise RuntimeError(f"the grader's worker did not start within {STARTUP_LIMIT} s")
                    yield current, (f"stopped after {time_limit:g} s: the kernel does not finish (an endless loop, "
                                    "or a barrier that not every work-item reaches?)"), time.monotonic() - started
                    return
                chunk = os.read(worker.stdout.fileno(), 65536)
                if not chunk:   # the worker is gone before it reported `current`
                    yield current, _gone(worker, errors, announced), time.monotonic() - started
                    return
                *lines, buffer = (buffer + chunk).split(b"\n")
                for message in _messages(lines):
                    if "start" in message:
                        announced = True
                        current, started = message["start"], time.monotonic()
                        deadline = started + (max(time_limit, BUILD_LIMIT) if current == "build" else time_limit)
                    elif "done" in message:
                        if message.get("suspect") and not message.get("fresh"):
                            # an exception in the host code, after other checks ran kernels in this
                            # process: perhaps one of them corrupted its memory. Again, in a fresh worker.
                            return
                        yield message["done"], message["reason"], message["seconds"]
                        if message["done"] == pending[-1] or (message["done"] == "build" and message["reason"]):
                            return
        finally:
            selector.close()
            _kill(worker)


def _messages(lines):
    """The worker's reports among the lines of its stdout (a kernel's printf may be there too)."""
    for line in lines:
        try:
            message = json.loads(line)
        except ValueError:
            continue
        if isinstance(message, dict) and message.get("grade-worker") is not None:
            yield message


def _gone(worker, errors, announced):
    """The reason of a worker that exited before it reported its check. Before it announced any
    check it is not the student's kernel (no OpenCL device, a broken install...): that is raised."""
    worker.wait()
    errors.seek(0)
    stderr = errors.read()
    if not announced:
        last = (stderr.strip().splitlines() or [f"exit status {worker.returncode}"])[-1]
        if "NoOpenCLError: " in last:
            raise NoOpenCLError(last.split("NoOpenCLError: ", 1)[1])
        raise RuntimeError(f"the grader's worker did not start: {last}")
    return _crash_reason(worker.returncode, stderr)


def _kill(worker):
    if worker.poll() is None:
        try:
            os.killpg(worker.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        worker.wait()
    if worker.stdout:
        worker.stdout.close()


def _crash_reason(returncode, stderr):
    last = (stderr.strip().splitlines() or ["no message"])[-1]
    how = f"exit status {returncode}"
    if returncode < 0:
        try:
            how = signal.Signals(-returncode).name
        except ValueError:
            how = f"signal {-returncode}"
    if last == "no message" and how == "SIGSEGV":
        last = "a segmentation fault"
    return f"the check crashed ({how}; an out-of-bounds access?): {last}"
