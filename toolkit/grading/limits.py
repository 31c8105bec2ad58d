"""The limits on the worker subprocess that runs a student's kernel (runner.py starts it).

A kernel can loop for ever, and its source can make the compiler expand macros without end, so
the worker runs
  - with time limits, enforced by the grader: start-up, the build, each check (runner.py);
  - under resource limits (setrlimit): memory, CPU time, file size, no core files;
  - with a clean environment (only what Python, pyopencl and the OpenCL runtimes need: nothing
    of the grader's own settings or secrets reaches a kernel's build or the report), in a
    temporary folder of its own as the current folder;
  - where the grader runs as root (Gradescope's container), as another, unprivileged user
    (Limits.user): a kernel that took the worker's process over could write its own folders,
    that user's home and what the system lets everyone write, nothing of root's (results.json);
  - and dies with the grader: a parent-death signal (Linux), and the grader turns SIGTERM and
    SIGHUP into an exit that kills the worker and removes its folder (stop_on_signals).
"""
import ctypes
import math
import os
import pwd
import signal
import sys
import threading
from contextlib import contextmanager
from dataclasses import dataclass

from toolkit.core.config import environment_copy

try:
    import resource
except ImportError:      # Windows: no setrlimit, so no grading there (require_limits says so)
    resource = None

# Seconds per check. A check takes 0.1-3 s on an idle 2-core CPU with warm kernel caches, but the
# first launch of each kernel compiles it (PoCL), and a fresh machine pays that inside the check:
# up to 6.5 s cold here (parallel_connect's `image`), past 10 s on a loaded CI machine. A loop that
# never ends in one function costs the few checks that call it this much each.
TIME_LIMIT = 30
MAX_TIME_LIMIT = 3600   # seconds: a longer limit per check is a typo, or `inf`


@dataclass(frozen=True)
class Limits:
    """The worker's limits besides the per-check time limit."""
    startup: float = 60     # seconds for a worker to start (Python, numpy, pyopencl, the OpenCL queue)
    build: float = 180      # seconds to build a submission's programs (a cold compiler cache)
    # Bytes of data (RLIMIT_DATA: what malloc and mmap give, not the address space that OpenCL
    # runtimes reserve). A worker needs ~0.4 GB; a macro bomb reaches 4 GiB in ~75 s (2 cores).
    memory: int = 4 * 2**30
    file_size: int = 256 * 2**20   # bytes in one file it writes (kernel caches: a few MB)
    # The account the worker runs as (None: the grader's own). Only root can switch to it: the
    # Gradescope autograder does (gradescope_run.py). Its home holds the worker's kernel caches.
    user: str = None


def check_time_limit(seconds):
    """`seconds` if it is a usable time limit per check; a ValueError that says why otherwise."""
    if not isinstance(seconds, (int, float)) or isinstance(seconds, bool) or not math.isfinite(seconds) \
            or not 0 < seconds <= MAX_TIME_LIMIT:
        raise ValueError(f"--time-limit must be a number of seconds above 0 and at most {MAX_TIME_LIMIT}, "
                         f"got {seconds!r}")
    return seconds


# What the worker's environment keeps of the grader's: Python's and the loader's paths, the
# home and cache folders (pyopencl's and PoCL's kernel caches), the locale, and the settings of
# the OpenCL runtimes and of the toolkit itself.
_KEPT = ("PATH", "HOME", "USER", "LOGNAME", "LANG", "LC_ALL", "LC_CTYPE", "LD_LIBRARY_PATH", "PYTHONPATH",
         "XDG_CACHE_HOME", "CUDA_VISIBLE_DEVICES", "ROCR_VISIBLE_DEVICES", "GPU_DEVICE_ORDINAL")
_KEPT_PREFIXES = ("POCL_", "PYOPENCL_", "OCL_", "OPENCL_", "OCLGRIND_", "CL_CONFIG_", "TOOLKIT_")


def worker_account(limits):
    """The password entry of the user the worker runs as, or None (it runs as the grader). A
    ValueError if there is no such user, or the grader cannot switch to it (it is not root)."""
    if limits.user is None:
        return None
    try:
        account = pwd.getpwnam(limits.user)
    except KeyError:
        raise ValueError(f"the grader's worker should run as user {limits.user!r}, which does not exist") from None
    if os.geteuid() != 0 and account.pw_uid != os.geteuid():
        raise ValueError(f"only root can run the grader's worker as user {limits.user!r}")
    return account


def worker_environment(folder, python_path, account=None):
    """The worker's environment: the kept variables, `python_path` first on PYTHONPATH, and
    `folder` as its temporary folder; as `account` (a password entry), its home and cache."""
    env = {k: v for k, v in environment_copy().items() if k in _KEPT or k.startswith(_KEPT_PREFIXES)}
    if account is not None:
        env.update(HOME=account.pw_dir, USER=account.pw_name, LOGNAME=account.pw_name,
                   XDG_CACHE_HOME=os.path.join(account.pw_dir, ".cache"))
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(python_path), env.get("PYTHONPATH")) if p)
    env["TMPDIR"] = str(folder)
    env["OCLGRIND_DATA_RACES"] = env.get("OCLGRIND_DATA_RACES", "1")   # the compaction `races` check
    return env


def cpu_seconds(limits, time_limit, checks):
    """The worker's CPU time limit: every core busy for its whole time. The grader's clock stops
    it first; this stops a worker that the grader, for whatever reason, no longer watches."""
    wall = limits.startup + limits.build + checks * time_limit
    return int(wall * (os.cpu_count() or 1)) + 60


_PR_SET_PDEATHSIG = 1
_prctl = None
if sys.platform.startswith("linux"):
    try:   # loaded here, not after the fork: a dlopen in the child could deadlock
        _prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        _prctl = None


def limit_worker(limits, cpu_limit, account=None):
    """The function Popen runs in the child before the worker starts (preexec_fn); as `account`
    (a password entry, looked up before the fork) if given."""
    parent = os.getpid()

    def apply():
        for which, value, hard in ((resource.RLIMIT_DATA, limits.memory, limits.memory),
                                   (resource.RLIMIT_FSIZE, limits.file_size, limits.file_size),
                                   (resource.RLIMIT_CORE, 0, 0),   # a crashing compiler writes no core file
                                   (resource.RLIMIT_CPU, cpu_limit, cpu_limit + 10)):   # SIGXCPU, then SIGKILL
            _, now = resource.getrlimit(which)
            if now != resource.RLIM_INFINITY:   # never above the limits the grader runs under
                value, hard = min(value, now), min(hard, now)
            resource.setrlimit(which, (value, hard))
        if account is not None and os.geteuid() != account.pw_uid:   # no group of the grader's is kept
            os.setgroups([])
            os.setgid(account.pw_gid)
            os.setuid(account.pw_uid)
        if _prctl is not None:
            _prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
            if os.getppid() != parent:   # the grader died before the signal was set up
                os.kill(os.getpid(), signal.SIGKILL)
    return apply


class GradingStopped(SystemExit):
    """The grader got SIGTERM or SIGHUP: it exits (128 + the signal) after its clean-up."""


def require_limits():
    """OSError where a worker's limits cannot be set: Windows has neither setrlimit nor SIGHUP."""
    if resource is None or not hasattr(signal, "SIGHUP"):
        raise OSError("the grader runs a submission under POSIX resource limits (setrlimit), which "
                      "this system does not have: grade on Linux or macOS (WSL on Windows)")


@contextmanager
def stop_on_signals():
    """Within: SIGTERM and SIGHUP raise GradingStopped, so that the `finally` clauses kill the
    worker and remove its folder (their default action would leave both behind). A second
    signal during that clean-up is ignored. Only the main thread can set signal handlers.
    Every grading run starts here, so here it refuses a system without the limits."""
    require_limits()
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    signals = (signal.SIGTERM, signal.SIGHUP)

    def stop(signum, frame):
        for s in signals:
            signal.signal(s, signal.SIG_IGN)
        raise GradingStopped(128 + signum)

    before = {s: signal.signal(s, stop) for s in signals}
    try:
        yield
    finally:
        for s, handler in before.items():
            signal.signal(s, handler)
