"""The worker subprocess that runs the checks of one submission (runner.py starts it):

    python -m toolkit.grading.worker NAME FOLDER SHOWN DEVICE INPUTS REPORT_FD CHECK...

reads the run's nonce from stdin, then runs the checks in order, each announced ({"start": check})
and reported ({"done": check, "reason": ...}) as a line of JSON on the pipe REPORT_FD (channel.py),
so the grader can time each one and knows which one crashed. INPUTS: 0 for the checks' public
inputs, another number for hidden ones (Context.rng). A student's kernel runs only here;
its printf goes to stdout, which the grader discards."""
import os
import re
import sys
import time

from toolkit.grading import stubs
from toolkit.grading.assignment import NEEDS_REFERENCE, SKIPPED, CheckFailed, CheckSkipped
from toolkit.grading.channel import report_line
from toolkit.grading.checks import ASSIGNMENTS
from toolkit.grading.context import Context
from toolkit.opencl.program import KernelBuildError


class Reports:
    """The worker's end of the report pipe."""

    def __init__(self, fd, nonce):
        os.set_inheritable(fd, False)   # not for the compiler's or anyone else's subprocesses
        self.fd, self.nonce = fd, nonce

    def say(self, **fields):
        self.write(report_line(self.nonce, **fields))

    def write(self, line):
        while line:
            line = line[os.write(self.fd, line):]


def run_worker(args, reports):
    """Run the checks `args` names (see the module docstring), "build" among them."""
    name, folder, shown, device, inputs, *names = args
    a = ASSIGNMENTS[name]
    c = Context(folder, a, device or None, shown, [n for n in names if n != "build"], int(inputs))   # fails (no device): the grader reports it as a crash
    for check_name in names:
        reports.say(start=check_name)
        suspect, start = False, time.perf_counter()
        try:
            if check_name == "build":
                a.build(c)
            else:
                next(k for k in a.checks if k.name == check_name).run(c)
            reason = None
        except CheckFailed as failed:
            reason = str(failed)
        except CheckSkipped as skipped:
            reason = SKIPPED + str(skipped)
        except stubs.AssignmentNotWritten:
            # The student edition holds the stub in place of the reference solution: a check that
            # compares with it is the instructor's; the build step's other programs build in their checks.
            reason = None if check_name == "build" else SKIPPED + NEEDS_REFERENCE
        except KernelBuildError as error:
            reason = _build_reason(str(error), a.replaces, shown)
        except MemoryError as error:
            # In the build: the compiler's allocation failed at the worker's memory limit, and the
            # runtime said so (pybind11 makes a C++ bad_alloc a MemoryError) instead of aborting.
            reason = ("the compiler ran out of memory while building your kernel (at the worker's memory "
                      "limit: a macro that expands without end?)") if check_name == "build" else (
                      f"MemoryError: {str(error).strip()}".strip())
            suspect = check_name != "build"
        except Exception as error:   # a broken kernel can make the host code fail anywhere
            text = str(error).strip().splitlines()
            reason = f"{type(error).__name__}: {text[0] if text else ''}".strip()
            suspect = True   # ... even in a later check, if it corrupted this process's memory
        reports.say(done=check_name, reason=reason, suspect=suspect, seconds=time.perf_counter() - start)
        if check_name == "build" and reason:
            break


def _build_reason(log, replaces, shown):
    """The compiler's first error, at the student's file and line (their file is built as `replaces`)."""
    lines = [line.strip() for line in log.splitlines()]
    located = [line for line in lines if "error" in line.lower() and re.search(r"\.(cl|h):\d+", line)]
    errors = located or [line for line in lines if "error:" in line.lower()]
    first = errors[0] if errors else (lines[0] if lines else "no compiler message")
    return first.replace(f"{replaces}:", f"{shown}:")


def main(argv):
    *args, fd = argv[:6]
    reports = Reports(int(fd), sys.stdin.readline().strip())
    run_worker(args + argv[6:], reports)


if __name__ == "__main__":
    main(sys.argv[1:])
