"""The compiled BVH build of a big scene, in a short-lived process of its own.

Why: numba's compiler (LLVM) stays in the memory of any process that has used it, about 120 MB,
even when it only loads the build's machine code from its cache. A renderer of a million
triangles needs that memory for the scene and its OpenCL runtime (issue 49: the whole `render`
under 600 MB). So toolkit/core/bvh.py hands big builds to a child process, which uses numba,
sends the tree back and exits, and its memory goes with it.

The child is this file run as a script (`python build_process.py`): it imports numpy and numba
and the two toolkit modules it runs, sah_build.py and wide_children.py, not the toolkit's
package (whose import starts pyopencl). Arrays travel through its stdin and stdout in numpy's .npy format;
the parent and the child take turns, so neither waits on a full pipe:

    parent -> child   vertices, triangles, settings (leaf size, bins, progress step, progress bar?)
    child -> parent   lo, hi, first, count, axis, order, depth (sah_build.build)
    parent -> child   each node's surface area as the device's float32 boxes give it, the widths
    child -> parent   per width: kids, index_of, depth_of, stack_of (wide_children.wide_children)

Its progress bar and any error message go to the parent's stderr.

The child's start, Python with numpy and numba and the build's machine code from numba's cache,
costs about 1.2 s of CPU before it can build. So it starts warm: it runs the build and the
wide children once on a few triangles (which loads their code) before it waits for the scene.
And the scene's loader starts it early (`start_early`, when the meshes are big), so that its
start runs on the second core while the first reads the meshes; BuildProcess takes that child.
"""
import atexit
import contextlib
import importlib
import os
import subprocess
import sys
import types
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


class _Stream:
    """A pipe seen by numpy's .npy reader and writer as a plain stream: they read and write it
    in chunks, never seek, and never hand it to C's file functions (which a pipe can upset)."""

    def __init__(self, pipe):
        self.pipe = pipe

    def read(self, size=-1):
        return self.pipe.read(size)

    def write(self, data):
        return self.pipe.write(data)


def send(pipe, *arrays):
    stream = _Stream(pipe)
    for array in arrays:
        np.lib.format.write_array(stream, np.asarray(array), allow_pickle=False)
    pipe.flush()


def receive(pipe, count):
    stream = _Stream(pipe)
    return [np.lib.format.read_array(stream, allow_pickle=False) for _ in range(count)]


def _start():
    # glibc's malloc keeps freed arrays of up to 32 MB in its heap for reuse (its threshold for
    # mapping memory of its own grows with each big array freed), and the child's resident memory
    # grows with each: with arrays of 1 MB and more always mapped, and unmapped when freed, the
    # child of a million triangles peaks at about 270 MB instead of 340 (other C libraries ignore this).
    from toolkit.core.config import environment_copy   # here: the child runs this file without the toolkit
    env = environment_copy()
    env.setdefault("MALLOC_MMAP_THRESHOLD_", str(1 << 20))
    return subprocess.Popen([sys.executable, str(HERE / "build_process.py")], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, env=env)


_early = []         # the child start_early started, until a BuildProcess takes it


def start_early():
    """Start the build's process now, for the next BuildProcess to take. A child no build takes
    is ended when this process exits."""
    if not _early:
        _early.append(_start())


@atexit.register
def _end_unused():
    for process in _early:
        process.kill()
        process.wait()
        process.stdin.close()
        process.stdout.close()
    _early.clear()


class BuildProcess:
    """The parent's end: `with BuildProcess() as child: child.send(...); child.receive(n)`."""

    def __enter__(self):
        self.process = _early.pop() if _early else _start()
        return self

    def send(self, *arrays):
        try:
            send(self.process.stdin, *arrays)
        except (BrokenPipeError, OSError):
            self._failed()

    def receive(self, count):
        try:
            return receive(self.process.stdout, count)
        except (ValueError, OSError):          # a short or garbled stream: the child stopped
            self._failed()

    def _failed(self):
        try:
            code = self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:       # stuck writing to a pipe no one reads any more
            self.process.kill()
            code = self.process.wait()
        raise RuntimeError(f"the BVH build process ({sys.executable} {HERE / 'build_process.py'}) stopped with "
                           f"exit code {code}; its messages, if any, are above")

    def __exit__(self, kind, error, trace):
        if kind is not None:
            self.process.kill()         # stopped here (an error, Ctrl-C): the child's work is not wanted
        for pipe in (self.process.stdin, self.process.stdout):
            with contextlib.suppress(OSError):      # a child that stopped early leaves a broken pipe
                pipe.close()
        code = self.process.wait()
        if kind is None and code != 0:
            self._failed()
        return False


def _load(name):
    """toolkit.core.`name`, imported without running the toolkit's __init__ (which imports
    pyopencl): its packages are made here as empty ones. The module keeps its real name, which
    numba's cache records (a cached function is found again under that name only)."""
    for package, folder in (("toolkit", HERE.parent), ("toolkit.core", HERE)):
        if package not in sys.modules:
            module = types.ModuleType(package)
            module.__path__ = [str(folder)]
            sys.modules[package] = module
    return importlib.import_module(f"toolkit.core.{name}")


def main():
    # The arrays get stdout to themselves: whatever else would print there (numba's debug
    # options, a library's message) goes to stderr, where the parent's messages go.
    stdin, stdout = sys.stdin.buffer, os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    sah_build, wide = _load("sah_build"), _load("wide_children")
    _warm_up(sah_build, wide)
    if not stdin.peek(1):           # the parent ended (or never needed this child): nothing to build
        return
    vertices, triangles, settings = receive(stdin, 3)
    leaf_size, bins, step, progress = (int(x) for x in settings)
    root = sah_build.BuildState.of_triangles(vertices, triangles)
    del vertices, triangles         # the build needs their boxes only (a million triangles: 36 MB)
    lo, hi, first, count, axis, order, depth = sah_build.build_from(root, leaf_size, bins, step, progress)
    del root
    send(stdout, lo, hi, first, count, axis, order, np.array(depth))
    del lo, hi, order
    area, widths = receive(stdin, 2)
    for width in widths:
        send(stdout, *wide.wide_children(first, count > 0, area, int(width)))
    # Everything is sent (and flushed): leave at once. Python's orderly exit tears numba's compiler
    # down for a quarter of a second, which the parent would wait for.
    os._exit(0)


def _warm_up(sah_build, wide):
    """Build a tree of a few triangles and its wide children: numba loads the machine code of both
    from its cache (half a second and more) before the scene arrives, not after."""
    corner = np.arange(64, dtype=np.float64).reshape(-1, 1) * np.array([[1.0, 0.5, 0.25]])
    vertices = np.concatenate([corner, corner + [1.0, 0.0, 0.0], corner + [0.0, 1.0, 0.0]])
    triangles = np.arange(len(vertices), dtype=np.int64).reshape(3, -1).T.copy()
    lo, hi, first, count, *_ = sah_build.build(vertices, triangles, 4, 16, 1 << 20, False)
    for width in (4, 8):
        wide.wide_children(first, count > 0, np.ones(len(first)), width)


if __name__ == "__main__":
    sys.path.pop(0)     # this folder: none of its files may be found in place of a library's
    main()
