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
make any kernel when that folder cannot be written. pyopencl reads PYOPENCL_NO_CACHE (no cache
at all) when it is imported, so this module runs before that: toolkit/__init__.py imports it
right after runtimes.py, and it does not import pyopencl itself.
"""
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

import platformdirs

from toolkit.core.package_data import APP_NAME
from toolkit.core.private_folder import private_folder, user_tag

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


def unwritable(folder):
    """Why `folder` cannot be made or written (tried with a file removed at once), or None."""
    try:
        Path(folder).mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".toolkit-", suffix=".probe"):
            pass
    except OSError as error:
        return f"cannot write to {folder}: {error.strerror or error}"
    return None


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


_checked = {}     # folder: its problem or None, looked at once per process
_said = set()     # the problems already reported
_no_cache = None  # why pyopencl was told to cache nothing (PYOPENCL_NO_CACHE), or None
_pocl_moved = None   # why PoCL's cache was moved to a private temporary folder, or None


def prepare_environment():
    """Before pyopencl is imported (and loads PoCL): make pyopencl's cache failures non-fatal,
    turn its caches off where pytools' cache folder cannot be written, and give PoCL a cache
    folder it can write (see the module's docstring)."""
    global _no_cache, _pocl_moved
    os.environ.setdefault("PYOPENCL_CACHE_FAILURE_FATAL", "")
    if "pyopencl" in sys.modules:
        return      # imported before the toolkit: too late to change how it caches
    if not os.environ.get("PYOPENCL_NO_CACHE"):
        _no_cache = unwritable(platformdirs.user_cache_dir("pytools", "pytools"))
        if _no_cache:
            os.environ["PYOPENCL_NO_CACHE"] = "1"
    if not os.environ.get("POCL_CACHE_DIR"):
        _pocl_moved = _private_pocl_cache()


def _private_pocl_cache():
    """PoCL's default cache folder ($XDG_CACHE_HOME/pocl, else ~/.cache/pocl): where it cannot
    be written, PoCL offers no device at all. Then POCL_CACHE_DIR names a folder of this user's
    own in the temporary folder, made 0700: PoCL loads the compiled kernels it finds there, so
    nobody else may write to it. Returns what was done, or None."""
    home = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    problem = unwritable(os.path.join(home, "pocl"))
    if not problem:
        return None
    root = Path(tempfile.gettempdir()) / f"{APP_NAME}-{user_tag()}"
    try:
        os.environ["POCL_CACHE_DIR"] = str(private_folder(private_folder(root) / "pocl-cache"))
    except OSError as error:     # UnsafeFolder among them: then PoCL keeps its default
        return f"PoCL's kernel cache: {problem}, and the temporary folder is not usable either ({error})"
    return f"PoCL's kernel cache is in {os.environ['POCL_CACHE_DIR']}: {problem}"


def build_cache_dir():
    """What `build` passes as Program.build's cache_dir: TOOLKIT_CACHE_DIR or pyopencl's default
    folder, or False (build without the cache) when that folder cannot be used (said once)."""
    if _pocl_moved:
        cache_failed(_pocl_moved, "")
    if _no_cache:
        cache_failed(_no_cache)
        return False
    folder = os.environ.get("TOOLKIT_CACHE_DIR") or str(default_folder())
    if folder not in _checked:
        _checked[folder] = cache_problem(folder)
    if _checked[folder] is None:
        return folder
    cache_failed(_checked[folder])
    return False


def cache_failed(problem, what="pyopencl's kernel cache is not used, kernels are built without it: "):
    """Say once per process that kernels are built without pyopencl's cache, and why."""
    if problem not in _said:
        _said.add(problem)
        warnings.warn(KernelCacheWarning(what + problem), stacklevel=3)


def build_with_cache(program, options, compiler_warning):
    """program.build(options) through pyopencl's cache where it can be used, else without it.

    pyopencl reports a cache that fails during the build (a lock it waited a minute for, an
    entry it cannot write) as a warning with a traceback, and then builds without the cache:
    that warning becomes the one KernelCacheWarning, and the folder is not tried again. The
    compiler's warnings (`compiler_warning`, cl.CompilerWarning) are left out: program.build
    shows the real ones. Returns (the program, the text of those compiler warnings: for a
    binary from the cache, the build log pyopencl stored with it)."""
    # A binary loses its parameters' names: Intel's CPU runtime answers get_arg_info of a program
    # made from a cached binary with KERNEL_ARG_INFO_NOT_AVAILABLE, though it was built with
    # -cl-kernel-arg-info. Such a build (tests/test_kernel_args.py) is made from source every time.
    cache_dir = False if ARG_INFO_OPTION in options else build_cache_dir()
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
            if cache_dir:
                _checked[cache_dir] = _exception_line(text)
            cache_failed(_checked.get(cache_dir) or _exception_line(text))
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return program, "\n".join(compiler_output)


def _exception_line(text):
    """The exception's own line of pyopencl's "[begin exception] ... [end exception]" warning."""
    lines = [line.strip() for line in text.split("[end exception]")[0].splitlines() if line.strip()]
    return lines[-1] if lines else "pyopencl could not use it"


prepare_environment()
