"""One program builder for every technique.

It inlines `#include "file.h"` from cl/ (with #line markers so compiler messages name our
files and lines), adds `-D` defines that describe the scene (absent features are not
compiled), and memoises builds per (source text with includes, defines, device) in the
context's Builds, which the queue carries (builds.py). Across processes pyopencl's binary cache
(kernel_cache.py: built without it where it cannot be used) and PoCL's kernel cache keep compiled
code on disk.
"""
import hashlib
import importlib
import re
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pyopencl as cl

from toolkit.core.layout import LOCAL_SIZE, c_header
from toolkit.core.package_data import data_dir
from toolkit.core.config import config
from toolkit.opencl import kernel_times, lanes, runtimes
from toolkit.opencl.builds import BuiltProgram
from toolkit.opencl.kernel_cache import ARG_INFO_OPTION, build_with_cache
from toolkit.opencl.session import session

# LOCAL_SIZE (core/layout.py, where render's options take their default from) is the default
# work-group size. A program is built for one local size (the LOCAL_SIZE define: the kernels'
# reqd_work_group_size and __local arrays) and must be launched with it: the techniques and the
# Compactor take `local_size` and pass it to both build() and launch().

# The includes we inline ourselves (the grader's sources.py checks a student's file against it).
INCLUDE_LINE = re.compile(r'^\s*#\s*include\s+"([^"]+)"\s*$')
# pyopencl's own headers (Philox, cl/philox.h): inlined from pyopencl's folder like ours, so that no
# -I option names this environment's path and kernel caches are shared by every checkout.
_PYOPENCL_INCLUDE = re.compile(r'^\s*#\s*include\s+<(pyopencl-[\w-]+)/([\w.]+)>\s*$')


def inlined_include(line):
    """Whether expand_includes inlines this line of a file (an include of ours or of pyopencl's)."""
    return bool(INCLUDE_LINE.match(line) or _PYOPENCL_INCLUDE.match(line))


def cl_dir():
    """The folder that holds our OpenCL sources (installed package or source checkout)."""
    return data_dir("toolkit.cl", "cl", "common.h")


def toolkit_source(name):
    """The text of cl/<name>, the toolkit's own file, read as every build reads it (default_sources)."""
    return default_sources().read(cl_dir() / name)


def _pyopencl_include_dir():
    return Path(cl.__file__).parent / "cl"


class KernelBuildError(RuntimeError):
    """An OpenCL build failure, with the compiler log pointing into cl/ files."""


class WorkGroupTooLarge(ValueError):
    """A kernel that the device cannot run in work-groups of the size its program was built for."""


def check_work_group(kernel_name, local_size, kernel_limit, device_name):
    """Raise WorkGroupTooLarge when `local_size` is above the kernel's own limit on the device
    (CL_KERNEL_WORK_GROUP_SIZE). A device's maximum work-group size is not enough to know: Apple's
    CPU device allows fewer work-items to kernels that use barriers or local memory."""
    if local_size > kernel_limit:
        raise WorkGroupTooLarge(
            f"{device_name} runs kernel {kernel_name} in work-groups of at most {kernel_limit} work-items "
            f"(its CL_KERNEL_WORK_GROUP_SIZE), and the kernel is built for {local_size}: pick another "
            f"device (--device), or render with local_size={kernel_limit} or less (toolkit.render's option)")


class KernelBuildWarning(UserWarning):
    """A compiler warning in one of our kernels (the log's `warning:` lines)."""


# Warnings a compiler writes about its own doing, not about our source: NVIDIA's OpenCL compiler
# (driver 580, H200, results/gpu.md) says this of every kernel it builds.
COMPILER_NOTICES = ("is a kernel, so overriding noinline attribute",)


def warning_lines(log):
    """The lines of a build log that are warnings about the source (not progress, vectorization
    remarks or COMPILER_NOTICES)."""
    return [line for line in log.splitlines()
            if "warning:" in line.lower() and not any(notice in line for notice in COMPILER_NOTICES)]


# The most source text one build may have with its includes (characters). Ours have at most
# 154 000; a file that includes itself under many names, or one that large, stops here.
MAX_SOURCE_SIZE = 4_000_000


class Sources:
    """Where a build finds its files: `folder` first, then cl/, so that a file in `folder` replaces
    the toolkit's file of that name and a kernel of your own can include the toolkit's headers.
    pyopencl's headers find theirs beside them. The grader restricts what a student's file may
    include with a subclass (toolkit/grading/sources.py)."""

    def __init__(self, folder=None):
        self.folder = Path(folder) if folder is not None else None

    def find(self, name, includer=None, line=None):
        """The file that `#include "name"` at `line` of file `includer` means (None: the program)."""
        if includer is not None and _pyopencl_include_dir() in includer.parents:
            bases = [includer.parent]
        else:
            bases = [base for base in (self.folder, cl_dir()) if base is not None]
        for base in bases:
            if (base / name).is_file():
                return base / name
        raise KernelBuildError(f"OpenCL source not found: {bases[0] / name}")

    def read(self, path):
        """The text of a file that find() named (a subclass may refuse it or check it first)."""
        return path.read_text()

    def toolkit_only(self):
        """These rules on the toolkit's own files only (no folder): what the shared parts of a
        technique built from this Sources (its compactor, its film reduction) are built from."""
        return Sources()


# The Sources class of a build given no Sources of its own, as "module:Class". This one line is
# what the course's student edition changes (toolkit/grading/export.py): it names a subclass that
# refuses a cl/ file that is still an untouched assignment stub, so that a learner's render says
# what it needs instead of drawing black. The renderer itself knows nothing of the course.
DEFAULT_SOURCES = "toolkit.opencl.program:Sources"


def default_sources(folder=None):
    """A Sources of the DEFAULT_SOURCES class that looks in `folder` (then cl/)."""
    module, name = DEFAULT_SOURCES.split(":")
    return getattr(importlib.import_module(module), name)(folder)


def expand_includes(name, directory=None):
    """Source text of cl/<name> (or <directory>/<name>) with its quoted includes inlined, each
    file once however it is named. Includes are looked up in `directory`, then in cl/; a
    Sources as `directory` decides itself where a build finds its files."""
    sources = directory if isinstance(directory, Sources) else default_sources(directory)
    if type(sources) is not Sources or sources.folder is not None:
        return _Expansion(sources).include(name)   # a folder of the caller's, or a Sources with rules of its own
    # The toolkit's own files: kept for the process (the Session), since every render builds several
    # programs and putting one together again took ~6 ms (70% of an 8x8 render's time, 2026-12-07).
    # A file changed since (cl/ edited in a running notebook) makes it read again.
    kept_sources, key = session().expanded_sources, (cl_dir(), name)
    kept = kept_sources.get(key)
    if kept is not None and all(_file_stamp(path) == stamp for path, stamp in kept[1]):
        return kept[0]
    expansion = _Expansion(sources)
    text = expansion.include(name)
    kept_sources[key] = (text, tuple((path, _file_stamp(path)) for path in expansion.seen if isinstance(path, Path)))
    return text


def _file_stamp(path):
    """What says that a file has changed: its size and modification time (None once it is gone)."""
    try:
        st = path.stat()
    except OSError:
        return None
    return st.st_size, st.st_mtime_ns


class _Expansion:
    """One program's source being put together: the files inlined so far, by their resolved path
    (so that no file comes in twice under two names; "layout.h", generated, by its name), and its
    size (at most MAX_SOURCE_SIZE)."""

    def __init__(self, sources):
        self.sources, self.seen, self.size = sources, set(), 0

    def include(self, name, includer=None, line=None):
        if name == "layout.h":  # generated from the one description in toolkit/core/layout.py
            if name in self.seen:
                return ""
            self.seen.add(name)
            return self._counted('#line 1 "layout.h (generated by toolkit/core/layout.py)"\n' + c_header())
        return self._file(self.sources.find(name, includer, line), name)

    def _file(self, path, name):
        if path.resolve() in self.seen:
            return ""
        self.seen.add(path.resolve())
        out = [f'#line 1 "{name}"']
        for number, line in enumerate(self.sources.read(path).splitlines(), start=1):
            match, theirs = INCLUDE_LINE.match(line), _PYOPENCL_INCLUDE.match(line)
            if match:
                out.append(self.include(match.group(1), path, number))
                out.append(f'#line {number + 1} "{name}"')
            elif theirs:   # its own quoted includes are found beside it, in its folder
                out.append(self._file(_pyopencl_include_dir() / theirs.group(1) / theirs.group(2), theirs.group(2)))
                out.append(f'#line {number + 1} "{name}"')
            else:
                out.append(self._counted(line))
        return "\n".join(out) + "\n"

    def _counted(self, text):
        self.size += len(text) + 1
        if self.size > MAX_SOURCE_SIZE:
            raise KernelBuildError(f"the source with its includes is over {MAX_SOURCE_SIZE:,} characters "
                                   "(a file included under several names, or one that large?)")
        return text


def define_options(defines):
    options = []
    for key in sorted(defines):
        value = defines[key]
        if value is False or value is None:
            continue
        if value is True:
            options.append(f"-D{key}=1")
        elif isinstance(value, float):
            options.append(f"-D{key}={value!r}f")
        else:
            options.append(f"-D{key}={value}")
    return options


def builtins_are_calls(device):
    """Whether the device's compiler leaves OpenCL's built-in functions (dot, sqrt, ...) as calls:
    PoCL links its built-in library after optimising the kernel (cl/inline_builtins.h)."""
    return "Portable Computing Language" in device.platform.name


def build(queue, name, defines=None, directory=None, arg_info=False, binary_cache=True):
    """The built program for cl/<name> (or <directory>/<name>) under `defines`, memoised in the
    Builds of `queue`'s context (a builds.Queue: device.get_queue makes them).

    With `directory`, `name` and its quoted includes are read from there first, then from cl/,
    so a kernel of your own can include the toolkit's headers. `defines["LOCAL_SIZE"]` (default
    LOCAL_SIZE) is the work-group size the program must be launched with (launch's local_size).
    `arg_info`: keep the kernels' parameter names (-cl-kernel-arg-info), for
    kernel.get_arg_info (tests/test_kernel_args.py compares them with the names the host passes).
    `binary_cache=False`: compiled from source, past pyopencl's binary cache (and not stored there).
    The context's SIMD-lanes setting (toolkit/opencl/lanes.py) is applied to every kernel;
    vector_widths(program) says what the compiler did with it."""
    builds, device = queue.builds, queue.device
    source, options = build_inputs(queue, name, defines, directory, arg_info)
    key = hashlib.sha256("\0".join([source, " ".join(options), device.name, device.platform.name,
                                    device.driver_version, cl.VERSION_TEXT]).encode()).hexdigest()
    if key in builds.programs:
        found = builds.programs[key]
        builds.log.append((name, 0.0, True))
        builds.lanes_log.append((name, builds.lanes, found.vector_widths))
        return found
    start = time.perf_counter()
    program, retrieved = _compile(BuiltProgram(queue.context, source), name, source, options, binary_cache)
    log = relocate(_build_log_text(program), source)
    if (session().verbose_builds or config().verbose) and log.strip():
        print(f"--- build log of {name} on {device.name.strip()} ---\n{log}", file=sys.stderr)
    real = warning_lines(log)
    if real and "-Werror" in options:  # for compilers that ignore the option (Oclgrind)
        raise KernelBuildError(_format_build_error(name, log, options))
    if real:
        warnings.warn(KernelBuildWarning(f"{name}: " + "\n".join(real)), stacklevel=2)
    builds.log.append((name, time.perf_counter() - start, False))
    # A program from pyopencl's binary cache has no log of its own: pyopencl hands over the one
    # it stored with the binary (`retrieved`), which is where the widths then come from.
    program.vector_widths = lanes.vector_widths(log + "\n" + retrieved)
    builds.lanes_log.append((name, builds.lanes, program.vector_widths))
    builds.programs[key] = program
    return program


def build_inputs(queue, name, defines=None, directory=None, arg_info=False):
    """(source, options): what build() hands the compiler of `queue`'s device for cl/<name>
    under `defines` (build's arguments). The offline GPU build (toolkit/verify/offline_build.py)
    hands the same to clang, so that it compiles what the host would build on a GPU."""
    defines = dict(defines or {})
    defines.setdefault("LOCAL_SIZE", LOCAL_SIZE)
    device = queue.device
    if builtins_are_calls(device):
        defines.setdefault("BUILTINS_ARE_CALLS", True)   # cl/inline_builtins.h writes them out
    source = lanes.source_prefix(queue.builds.lanes, device.native_vector_width_float) + expand_includes(name, directory)
    options = define_options(defines)
    if arg_info:
        options.append(ARG_INFO_OPTION)
    if config().werror:
        options.append("-Werror")  # the test suite: any compiler warning fails the build
    if "Intel" in device.platform.name:
        # Intel's vectorizer setting (toolkit/opencl/lanes.py) changes the code built from the same
        # options: name it in them, so that pyopencl's binary cache keeps the two apart.
        use = config().intel_use_vectorizer
        options.append(f"-DINTEL_VECTORIZER_{'True' if use is None else use}")
    return source, options


def _compile(program, name, source, options, binary_cache):
    """(the built program, the build log pyopencl kept with a cached binary or "")."""
    try:
        with runtimes.compiler_output_shown():   # pyopencl then warns with the stored log itself
            return build_with_cache(program, options, cl.CompilerWarning, binary_cache)
    except cl.RuntimeError as error:
        raise KernelBuildError(_format_build_error(name, relocate(str(error), source), options)) from None


def vector_widths(built):
    """{kernel: work-items per vector} that the compiler reported for a program build() made."""
    return dict(built.vector_widths)


def _build_log_text(program):
    try:
        return "\n".join(program.get_build_info(d, cl.program_build_info.LOG) or ""
                         for d in program.get_info(cl.program_info.DEVICES))
    except cl.Error:
        return ""


_LINE_MARKER = re.compile(r'^#line (\d+) "([^"]+)"')
# What compilers that ignore #line call the program's source (Oclgrind: "input.cl").
_WHOLE_SOURCE = re.compile(r'(?<![\w./<-])(input\.cl|<source>):(\d+):(\d+):')


def relocate(log, source):
    """Compiler locations in the expanded source turned into our files and lines. Most compilers
    follow the #line markers that expand_includes writes; some (Oclgrind) ignore them and name
    the whole source "input.cl", line N of the expanded text: those are mapped back here."""
    origin, file, line = [], "?", 0
    for text in source.splitlines():
        marker = _LINE_MARKER.match(text)
        origin.append((file, line))
        file, line = (marker.group(2), int(marker.group(1))) if marker else (file, line + 1)

    def mapped(match):
        number, column = int(match.group(2)), match.group(3)
        if not 1 <= number <= len(origin):
            return match.group(0)
        file, line = origin[number - 1]
        return f"{file}:{line}:{column}:"
    return _WHOLE_SOURCE.sub(mapped, log)


def _format_build_error(name, log, options):
    # pyopencl's error text holds every device's build log: one source of the log for every
    # implementation (asking the failed program for it returns nothing on some, e.g. Intel's).
    # Keep the compiler's lines that point into our sources first, they are what a learner reads.
    # Compilers put the location first ("broken.h:3:36: error: ...") or after the severity
    # (PoCL: "error: broken.h:3:36: ..."); layout.h's #line name has a note in parentheses.
    ours = [line for line in log.splitlines()
            if re.search(r'(^|\s)[^\s:]+\.(cl|h)( \([^)]*\))?:\d+', line.strip())]
    head = "\n".join(ours[:20]) if ours else ""
    return (f"OpenCL build of {name} failed (options: {' '.join(options)}).\n"
            + (f"Errors in our sources:\n{head}\n" if head else "")
            + f"Full compiler log:\n{log}")


def kernel(built, name, copy=0):
    """The kernel `name` of a program build() made, retrieved once per `copy` (each retrieval makes
    a new cl.Kernel). launch keeps each kernel object's last arguments: a loop whose buffers take
    turns (streams that swap every step) launches one copy per turn and sets no argument."""
    key = name if copy == 0 else (name, copy)
    if key not in built.kernels_by_name:
        built.kernels_by_name[key] = getattr(built, name) if copy == 0 else cl.Kernel(built, name)
    return built.kernels_by_name[key]


def padded(n, local_size=LOCAL_SIZE):
    """Global size: n rounded up to a multiple of the local size (kernels guard with `gid >= n`)."""
    return max(local_size, (n + local_size - 1) // local_size * local_size)


# Kernel arguments set once, not per launch. Setting the arguments is most of a launch's cost on
# PoCL (~165 us for 33 arguments, 2026-12-06, when a BDPT walk step launched two kernels of 16),
# and most of them (the scene, the pass's records and buffers) do not change between the launches
# of a pass.
# `launch` keeps, per kernel, a cl.Kernel of its own with the values last set (in the context's
# Builds: builds.py), and sets only the arguments that changed (cl.Kernel.set_arg; OpenCL keeps
# the others) before enqueue_nd_range_kernel. Its own cl.Kernel, because a kernel called directly
# (kernel(queue, ...)) sets all its arguments and would leave the record of values stale.


def _fingerprint(value):
    """What identifies a kernel argument's value: a buffer by identity, a numpy scalar or record
    by its bytes (copied: a record may be changed in place between launches); anything else is
    set at every launch."""
    if isinstance(value, np.generic):
        return (value.dtype, value.tobytes())
    if isinstance(value, cl.MemoryObjectHolder):
        return value
    return object()


def _set_arg(kernel, i, value):
    """kernel.set_arg, with numpy values (numbers, records) given as bytes directly. pyopencl's set_arg
    tries a value as a buffer, local memory and a sampler first, each failure a C++ exception: 10 us
    for an int on a quiet machine here against 0.4 us through _set_arg_buf (the method pyopencl's
    own generated kernel invokers use), and several times that while kernels run beside the host."""
    if isinstance(value, np.generic) and _SET_ARG_BUF:
        kernel._set_arg_buf(i, value)
    else:
        kernel.set_arg(i, value)


_SET_ARG_BUF = hasattr(cl.Kernel, "_set_arg_buf")   # pyopencl's private fast path; set_arg where it is gone


def _work_group_limit(kernel, device):
    """The most work-items per work-group the device runs this kernel with."""
    return kernel.get_work_group_info(cl.kernel_work_group_info.WORK_GROUP_SIZE, device)


def _same_fingerprint(previous, current):
    """Whether an argument's value is the one set before. Only tuples (numpy values) are compared
    with ==; buffers by identity, because pyopencl 2022.3 (Debian 12's) raises TypeError when a
    Buffer is compared with anything but another memory object."""
    if previous is current:
        return True
    return isinstance(previous, tuple) and isinstance(current, tuple) and previous == current


def _kept_by_identity(value):
    """Whether the same object given again is surely the same argument value: a buffer (set by
    identity anyway), an immutable numpy number or a read-only record (record.frozen); not a
    writable record (np.void), which may change in place."""
    if isinstance(value, np.void):
        return not value.flags.writeable
    return isinstance(value, _KEPT_TYPES)     # a numpy number is a 0-d scalar, never an array


_KEPT_TYPES = (cl.MemoryObjectHolder, np.number)


class _Launched:
    """What launch keeps per kernel: its own cl.Kernel, its name, and per argument the value last
    set (the object given, and whether that object is enough to know it: _kept_by_identity) and
    its fingerprint."""
    __slots__ = ("kernel", "own", "name", "values", "by_identity", "fingerprints")

    def __init__(self, kernel):
        self.kernel, self.name = kernel, kernel.function_name
        self.own = cl.Kernel(kernel.program, self.name)
        self.values = [_UNSET] * kernel.num_args
        self.by_identity = [False] * kernel.num_args
        self.fingerprints = [_UNSET] * kernel.num_args


def launch(queue, kernel, n, *args, local_size=LOCAL_SIZE):
    """Run `kernel` over n work-items in work-groups of `local_size` (the LOCAL_SIZE its program
    was built with) and a padded global size, setting only the arguments that differ from its
    previous launch. An argument given as the very object of the previous launch (a buffer, an
    np.int32 made once) costs one comparison: a launch's Python work was ~10x the enqueue's on PoCL
    (about 25 us against 3 us of the thread's CPU for 12 arguments, 2026-12-06)."""
    launched = queue.builds.launched
    state = launched.get(kernel.int_ptr)
    if state is None or state.kernel is not kernel:
        # Keyed by the handle, checked by identity: a freed kernel's handle can be reused by
        # another kernel, which must not inherit this one's arguments (or program).
        check_work_group(kernel.function_name, local_size, _work_group_limit(kernel, queue.device),
                         queue.device.name.strip())
        state = launched[kernel.int_ptr] = _Launched(kernel)
    values = state.values
    if len(args) != len(values):
        raise TypeError(f"{state.name} takes {len(values)} arguments, {len(args)} given")
    by_identity = state.by_identity
    for i, value in enumerate(args):
        previous = values[i]
        if value is previous and by_identity[i]:
            continue
        fingerprint = _fingerprint(value)
        if not _same_fingerprint(state.fingerprints[i], fingerprint):
            _set_arg(state.own, i, value)
            state.fingerprints[i] = fingerprint
        if value is not previous:
            values[i], by_identity[i] = value, _kept_by_identity(value)
    event = cl.enqueue_nd_range_kernel(queue, state.own, (padded(n, local_size),), (local_size,))
    if queue.recording is not None:
        kernel_times.note(queue, state.name, event)   # kept only while a phase timing records
    return event


_UNSET = object()
