"""pyopencl's binary cache of built kernels, and what the toolkit does when it cannot be used.

pyopencl keeps each built program on disk (`Program.build(cache_dir=...)`), which saves the
rebuild of every kernel in every new process. Two things make that cache fail: a folder that
cannot be written (a read-only home, a cache left owned by root by a `sudo` run), and a `lock`
file left by a process that died while it held it, on which pyopencl waits a minute per build
and then gives up. When it gives up, pyopencl reads the environment variable
PYOPENCL_CACHE_FAILURE_FATAL to decide whether to raise; unset, that read itself fails with a
KeyError. So the toolkit sets it (empty: not fatal) for every process, looks at the cache
folder once before the first build, and when the cache cannot be used builds without it and
says so once (a KernelCacheWarning; the command line shows it as one `warning:` line).

pyopencl also keeps the code that launches each kernel in pytools' cache folder, and fails to
make any kernel when that folder cannot be written: then pyopencl is told to cache nothing
(PYOPENCL_NO_CACHE, before its import). What the environment tells pyopencl and PoCL is set in
toolkit/opencl/runtimes.py; this module decides, per build, which folder pyopencl's cache is in.
"""
import sys
import time
import warnings
from pathlib import Path

import platformdirs

from toolkit.core.config import config
from toolkit.opencl import runtimes
from toolkit.opencl.runtimes import unwritable
from toolkit.opencl.session import session

# pyopencl holds its lock only while it reads or writes one cache entry, for milliseconds; a lock
# this old was left by a process that no longer runs (pyopencl itself gives up after 60 s).
STALE_LOCK_SECONDS = 20.0
# The option that keeps kernels' parameter names (program.build(arg_info=True)); such builds skip the cache.
ARG_INFO_OPTION = "-cl-kernel-arg-info"



class KernelCacheWarning(UserWarning):
    """pyopencl's kernel cache cannot be used: kernels are built without it (slower starts)."""


def default_folder():
    """pyopencl's own default cache folder (pyopencl/cache.py computes it the same way on Linux),
    so that the toolkit shares the builds of any other pyopencl program."""
    version = ".".join(str(i) for i in sys.version_info)
    return Path(platformdirs.user_cache_dir("pyopencl", "pyopencl")) / f"pyopencl-compiler-cache-v2-py{version}"


def cache_problem(folder, now=None):
    """Why pyopencl's cache at `folder` cannot be used (it cannot be written, or it holds a stale
    lock), or None."""
    folder = Path(folder)
    problem = unwritable(folder)
    if problem:
        return problem
    lock = folder / "lock"
    try:
        age = (time.time() if now is None else now) - lock.stat().st_mtime
    except FileNotFoundError:
        return None
    except OSError as error:
        return f"cannot read its lock file {lock}: {error.strerror or error}"
    if age > STALE_LOCK_SECONDS:
        return (f"its lock file {lock} is {age:.0f} s old, left by a process that stopped; delete it "
                "if no other OpenCL program is running")
    return None


def build_cache_dir():
    """What `build` passes as Program.build's cache_dir: TOOLKIT_CACHE_DIR or pyopencl's default
    folder, or False (build without the cache) when that folder cannot be used (said once)."""
    prepared = runtimes.prepare()
    if prepared.pocl_cache_moved:
        cache_failed(prepared.pocl_cache_moved, "")
    if prepared.no_pyopencl_cache:
        cache_failed(prepared.no_pyopencl_cache)
        return False
    folder = config().cache_dir or str(default_folder())
    problems = session().cache_problems      # each folder looked at once per process
    if folder not in problems:
        problems[folder] = cache_problem(folder)
    if problems[folder] is None:
        return folder
    cache_failed(problems[folder])
    return False


def cache_failed(problem, what="pyopencl's kernel cache is not used, kernels are built without it: "):
    """Say once per process that kernels are built without pyopencl's cache, and why."""
    said = session().cache_problems_said
    if problem not in said:
        said.add(problem)
        warnings.warn(KernelCacheWarning(what + problem), stacklevel=3)


def build_with_cache(program, options, compiler_warning, binary_cache=True):
    """program.build(options) through pyopencl's cache where it can be used (and `binary_cache`:
    False builds from source, uncached), else without it.

    pyopencl reports a cache that fails during the build (a lock it waited a minute for, an
    entry it cannot write) as a warning with a traceback, and then builds without the cache:
    that warning becomes the one KernelCacheWarning, and the folder is not tried again. The
    compiler's warnings (`compiler_warning`, cl.CompilerWarning) are left out: program.build
    shows the real ones. Returns (the program, the text of those compiler warnings: for a
    binary from the cache, the build log pyopencl stored with it)."""
    # A binary loses its parameters' names: Intel's CPU runtime answers get_arg_info of a program
    # made from a cached binary with KERNEL_ARG_INFO_NOT_AVAILABLE, though it was built with
    # -cl-kernel-arg-info. Such a build (tests/test_kernel_args.py) is made from source every time.
    cache_dir = False if ARG_INFO_OPTION in options or not binary_cache else build_cache_dir()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        program = program.build(options=options, cache_dir=cache_dir)
    compiler_output = []
    for w in caught:
        text = str(w.message)
        if issubclass(w.category, compiler_warning):
            compiler_output.append(text)
            continue
        if "caching failed" in text:
            problems = session().cache_problems
            if cache_dir:
                problems[cache_dir] = _exception_line(text)
            cache_failed(problems.get(cache_dir) or _exception_line(text))
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return program, "\n".join(compiler_output)


def _exception_line(text):
    """The exception's own line of pyopencl's "[begin exception] ... [end exception]" warning."""
    lines = [line.strip() for line in text.split("[end exception]")[0].splitlines() if line.strip()]
    return lines[-1] if lines else "pyopencl could not use it"
