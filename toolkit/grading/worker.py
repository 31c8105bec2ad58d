"""The worker subprocess that runs the checks of one submission (runner.py starts it):

    python -m toolkit.grading.worker NAME FOLDER SHOWN DEVICE CHECK...

runs the checks in order, each announced ({"start": check}) and reported ({"done": check,
"reason": ...}) as a line of JSON on stdout, so the grader can time each one and knows which one
crashed. A student's kernel runs only here."""
import json
import os
import re
import sys
import time

from toolkit.grading.assignment import CheckFailed
from toolkit.grading.checks import ASSIGNMENTS
from toolkit.grading.context import Context
from toolkit.opencl.program import KernelBuildError


def run_worker(args):
    """Run the checks `args` names (see the module docstring), "build" among them."""
    name, folder, shown, device, *names = args
    os.environ.setdefault("OCLGRIND_DATA_RACES", "1")   # Oclgrind's race detector (the compaction `races` check)
    os.environ.setdefault("PYOPENCL_CACHE_FAILURE_FATAL", "")   # pyopencl reads it when its cache fails
    a = ASSIGNMENTS[name]
    c = Context(folder, device or None, shown)   # fails (no device): the grader reports it as a crash
    ran = 0   # checks run in this worker so far (the build does not count)
    for check_name in names:
        _say(start=check_name)
        suspect, start = False, time.perf_counter()
        try:
            if check_name == "build":
                a.build(c)
            else:
                next(k for k in a.checks if k.name == check_name).run(c)
            reason = None
        except CheckFailed as failed:
            reason = str(failed)
        except KernelBuildError as error:
            reason = _build_reason(str(error), a.replaces, shown)
        except Exception as error:   # a broken kernel can make the host code fail anywhere
            text = str(error).strip().splitlines()
            reason = f"{type(error).__name__}: {text[0] if text else ''}".strip()
            suspect = True   # ... even in a later check, if it corrupted this process's memory
        _say(done=check_name, reason=reason, suspect=suspect, fresh=ran == 0, seconds=time.perf_counter() - start)
        if check_name == "build":
            if reason:
                break
        else:
            ran += 1


def _say(**message):
    """One report to the grader: a line of JSON, tagged, on a line of its own (a kernel's printf
    may have left a line unfinished)."""
    sys.stdout.write("\n" + json.dumps(dict({"grade-worker": 1}, **message)) + "\n")
    sys.stdout.flush()


def _build_reason(log, replaces, shown):
    """The compiler's first error, at the student's file and line (their file is built as `replaces`)."""
    lines = [line.strip() for line in log.splitlines()]
    located = [line for line in lines if "error" in line.lower() and re.search(r"\.(cl|h):\d+", line)]
    errors = located or [line for line in lines if "error:" in line.lower()]
    first = errors[0] if errors else (lines[0] if lines else "no compiler message")
    return first.replace(f"{replaces}:", f"{shown}:")


if __name__ == "__main__":
    run_worker(sys.argv[1:])
