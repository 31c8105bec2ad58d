"""The grader's side of the worker subprocess (worker.py runs the checks): start a worker under its
limits (limits.py), read its reports from their own pipe (channel.py), enforce the time limits,
and after a hang or a crash, a fresh worker for the checks that remain. Nothing here runs a
kernel: a student's kernel cannot hang or crash the grader, nor write its reports."""
import os
import secrets
import selectors
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

from toolkit.grading.channel import MAX_LINE, Expected, ProtocolError, one_line, parse_report
from toolkit.grading.limits import TIME_LIMIT, Limits, cpu_seconds, limit_worker, worker_account, worker_environment
from toolkit.opencl.device import NoOpenCLError

__all__ = ["TIME_LIMIT", "GraderError", "Limits", "run_checks"]

MAX_RUNS = 2        # runs of one check: a host exception after other checks ran is retried once, fresh
STDERR_TAIL = 8192  # bytes of the worker's stderr kept: its last lines say why it died
# The folder holding toolkit/ (the checkout, or site-packages): the worker runs this same toolkit.
TOOLKIT_PARENT = Path(__file__).resolve().parents[2]
WORKER = ["-m", "toolkit.grading.worker"]   # what the worker's Python runs (the tests put a fake here)


class GraderError(Exception):
    """The grader failed on one submission: its worker did not start, or sent a line that is not
    the report expected. Not the student's doing; the rest of a batch is still graded.
    `reasons` and `times` hold the checks graded before it failed."""

    def __init__(self, message, reasons=None, times=None):
        super().__init__(message)
        self.reasons, self.times = dict(reasons or {}), dict(times or {})


def run_checks(name, pending, folder, time_limit, device, shown, limits=Limits(), workdir=None, inputs=0):
    """Run the checks `pending` (the first is "build") in one worker subprocess, which reports
    each check's start and end. A check that runs past `time_limit` or crashes the worker gets its
    reason, the worker is killed, and a fresh one goes on with the remaining checks. A failed build
    stops the grading: every check then loses its points for that reason. `workdir`: the worker's
    current and temporary folder (None: a new one). Returns {check: None if it passed, else its
    one-line reason}, {check: seconds}; raises GraderError (with the checks graded so far) if the
    grader fails."""
    if workdir is None:
        with tempfile.TemporaryDirectory(prefix="grade-worker-") as workdir:
            return run_checks(name, pending, folder, time_limit, device, shown, limits, workdir, inputs)
    reasons, times, runs = {}, {}, Counter()
    pending = list(pending)
    while pending:
        # a fresh worker after a hang or crash builds first too (from the caches, under limits.build)
        session = list(pending) if pending[0] == "build" else ["build"] + pending
        try:
            for check_name, reason, seconds in _worker_session(name, session, folder, time_limit, device, shown,
                                                               limits, workdir, runs, inputs):
                if check_name == "build" and "build" in reasons:
                    if reason:   # it built before: the rebuild was stopped or crashed; the next check pays
                        reasons[pending[0]], times[pending[0]] = reason, seconds
                        pending.pop(0)
                    continue
                reasons[check_name], times[check_name] = reason, seconds
                pending.remove(check_name)
                if check_name == "build" and reason:
                    return dict(reasons, **{p: None for p in pending}), times
        except (ProtocolError, GraderError) as error:
            raise GraderError(f"the grader's worker sent {error}" if isinstance(error, ProtocolError) else str(error),
                              reasons, times) from None
    return reasons, times


def _worker_session(name, checks, folder, time_limit, device, shown, limits, workdir, runs, inputs=0):
    """One worker process: yields (check, reason, seconds) as the checks end; the last one it
    yields is the check it was stopped or crashed in (if any), and then it is gone. Start-up has
    limits.startup seconds, the build limits.build; each check's time limit starts at its start.
    A check that failed with a host exception after others ran here (the worker reports it as
    suspect: one of them may have corrupted its memory) ends the session, to run again in a fresh
    worker, at most MAX_RUNS times in all. `runs` counts the runs of each check."""
    nonce, expected = secrets.token_hex(16), Expected(checks)
    command = [sys.executable, *WORKER, name, str(folder), shown, device or "", str(int(inputs))]
    with _Worker(command, checks, nonce, limits, time_limit, workdir) as worker:
        started = time.monotonic()
        deadline = started + limits.startup
        while True:
            line = worker.next_line(deadline)
            if line is _TIMED_OUT or line is _GONE:
                worker.stop()
                check, reason = _last_words(expected, line, worker, time_limit, limits)
                yield check, reason, time.monotonic() - started
                return
            report = expected.accept(parse_report(line, nonce))
            if "start" in report:
                runs[report["start"]] += 1
                started = time.monotonic()
                deadline = started + (limits.build if report["start"] == "build" else time_limit)
                continue
            others_ran = expected.ended > 2   # other checks than the build and this one
            if report["suspect"] and others_ran and runs[report["done"]] < MAX_RUNS:
                return
            yield report["done"], report["reason"], report["seconds"]
            if expected.ended == len(checks) or (report["done"] == "build" and report["reason"]):
                return
            started = time.monotonic()
            deadline = started + limits.startup   # the worker's own code, up to the next start


def _last_words(expected, why, worker, time_limit, limits):
    """(check, reason) of a worker that timed out (`why` _TIMED_OUT) or died (_GONE)
    before it reported the end of the check it ran. Before any check started, or between two
    checks (the grader's own code), that is the grader's failure: GraderError."""
    if expected.ended == 0 and expected.running is None:
        if why is _TIMED_OUT:
            raise GraderError(f"the grader's worker did not start within {limits.startup:g} s")
        last = (worker.stderr_lines() or [f"exit status {worker.returncode}"])[-1]
        if "NoOpenCLError: " in last:
            raise NoOpenCLError(last.split("NoOpenCLError: ", 1)[1])
        raise GraderError(f"the grader's worker did not start: {one_line(last)}")
    check = expected.running
    if check is None:
        if why is _TIMED_OUT:
            raise GraderError("the grader's worker stopped between two checks")
        check = expected.checks[expected.ended]   # it died between two checks: the next one pays
    if why is _TIMED_OUT and check == "build":
        return check, (f"the build was stopped after {limits.build:g} s: the compiler did not finish (a macro "
                       "that expands without end?)")
    if why is _TIMED_OUT:
        return check, (f"stopped after {time_limit:g} s: the kernel does not finish (an endless loop, "
                       "or a barrier that not every work-item reaches?)")
    return check, _crash_reason(worker.returncode, worker.stderr_lines(), check == "build", limits)


def _crash_reason(returncode, stderr_lines, building, limits):
    """Why the worker died: the signal or exit status, and its last line on stderr."""
    last = one_line(stderr_lines[-1]) if stderr_lines else ""
    how = f"exit status {returncode}"
    if returncode < 0:
        try:
            how = signal.Signals(-returncode).name
        except ValueError:
            how = f"signal {-returncode}"
    if how == "SIGXCPU":
        return f"the worker used up its CPU time ({how}): the kernel does not finish?"
    if how == "SIGXFSZ":
        return f"the worker wrote a file over {limits.file_size // 2**20} MB ({how})"
    out_of_memory = any(word in " ".join(stderr_lines[-5:]).lower()
                        for word in ("out of memory", "bad_alloc", "allocation failed", "memoryerror"))
    memory = f"out of memory: the worker may use {limits.memory / 2**30:g} GiB"
    if building:
        why = memory if out_of_memory else "a compiler bug, or a source that it cannot handle"
        return f"the compiler crashed while building your kernel ({how}; {why})" + (f": {last}" if last else "")
    if out_of_memory:
        return f"the check ran {memory} ({how})"
    if not last and how == "SIGSEGV":
        last = "a segmentation fault"
    return f"the check crashed ({how}; an out-of-bounds access?): {last or 'no message'}"


_TIMED_OUT, _GONE = object(), object()   # what next_line returns instead of a line


class _Worker:
    """One worker subprocess (limits.py sets its limits) and its two pipes: its reports, and its
    stderr, of which the last lines are kept (they say why it died). Its stdout, where a kernel's
    printf writes, is discarded. Leaving the `with` kills it and its process group."""

    def __init__(self, command, checks, nonce, limits, time_limit, workdir):
        account = worker_account(limits)
        reports, ours = os.pipe()   # (read end, write end): the worker gets the write end only
        try:
            self.process = subprocess.Popen(
                command + [str(ours), *checks], stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE, pass_fds=(ours,), cwd=workdir, start_new_session=True,
                env=worker_environment(workdir, TOOLKIT_PARENT, account),
                preexec_fn=limit_worker(limits, cpu_seconds(limits, time_limit, len(checks)), account))
        except BaseException:
            os.close(reports)
            raise
        finally:
            os.close(ours)   # so that the pipe ends when the worker does
        self.reports, self.errors = reports, self.process.stderr.fileno()
        self._send_nonce(nonce)
        self.selector = selectors.DefaultSelector()
        self.selector.register(self.reports, selectors.EVENT_READ)
        self.selector.register(self.errors, selectors.EVENT_READ)
        self.buffer, self.tail = b"", b""

    def _send_nonce(self, nonce):
        try:
            self.process.stdin.write(nonce.encode() + b"\n")
            self.process.stdin.close()
        except OSError:   # it died at once: its stderr will say why
            pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()
        self.selector.close()
        os.close(self.reports)
        self.process.stderr.close()

    @property
    def returncode(self):
        return self.process.returncode

    def next_line(self, deadline):
        """The next line on the report pipe (without its newline), _TIMED_OUT at `deadline`, or
        _GONE once the worker has closed the pipe (it exited)."""
        while b"\n" not in self.buffer:
            if len(self.buffer) > MAX_LINE:
                raise ProtocolError(f"a line of more than {MAX_LINE} bytes")
            left = deadline - time.monotonic()
            if left <= 0:
                return _TIMED_OUT
            for key, _ in self.selector.select(timeout=left):
                chunk = os.read(key.fd, 65536)
                if key.fd == self.errors:
                    self._keep(chunk)
                elif not chunk:
                    self.stop(wait_for_exit=True)
                    return _GONE
                else:
                    self.buffer += chunk
        line, self.buffer = self.buffer.split(b"\n", 1)
        return line

    def _keep(self, chunk):
        if not chunk:   # stderr closed
            self.selector.unregister(self.errors)
        self.tail = (self.tail + chunk)[-STDERR_TAIL:]

    def stderr_lines(self):
        """The last lines the worker wrote to stderr (what is left in the pipe too)."""
        while self.errors in self.selector.get_map() and self.selector.select(timeout=0.2):
            chunk = os.read(self.errors, 65536)
            self._keep(chunk)
            if not chunk:
                break
        return [line for line in self.tail.decode("utf-8", "replace").splitlines() if line.strip()]

    def stop(self, wait_for_exit=False):
        """Kill the worker's process group (it may have started others), unless it exits by itself
        within a second after `wait_for_exit`, and reap it."""
        if wait_for_exit:
            try:
                self.process.wait(timeout=1)
            except subprocess.TimeoutExpired:
                pass
        if self.process.poll() is None:
            try:
                os.killpg(self.process.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            self.process.wait()
