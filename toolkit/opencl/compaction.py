"""Stream compaction on the device, two ways (van Antwerpen, HPG 2011, "Immediate Stream Compaction").

Kernels: cl/compact.cl, with the reusable device functions in cl/compact.h.

* ``method="multipass"``: an exclusive scan of the alive flags (our own work-group scan in
  local memory, a scan of the block sums, recursively, and an add-back), then a scatter
  pass. The output is ``np.flatnonzero(mask)`` exactly: the order is preserved (stable).
* ``method="immediate"``: one pass. Each work-group scans its flags in local memory,
  reserves room for its survivors with ONE ``atomic_add`` on a global counter, and every
  survivor writes its index directly. Within a work-group the order is kept; the order of
  the work-groups is the order of their atomics, so the output is the alive set in
  UNSPECIFIED BLOCK ORDER (it may differ from run to run).

Kernels that compact their own records while they run include "compact.h" and call
``immediate_compact_slot`` (see that file for the rules: no early return before it).
"""
import numpy as np
import pyopencl as cl
import pyopencl.array as cl_array

from toolkit.opencl import program
from toolkit.core.validate import local_size as checked_local_size

METHODS = ("immediate", "multipass")
_INT = np.dtype(np.int32).itemsize


class Compactor:
    """Compacts streams of alive flags into streams of the alive indices on `queue`'s device.

    ``last_stats`` describes the last call (for the SIMD counters and for teaching): the
    method, the stream length ``n``, the number of survivors ``count`` (None after
    compact_on_device: the count stayed on the device), the number of work-groups and of kernel
    launches it took.

    `local_size` is the work-group size its kernels are built for (LOCAL_SIZE) and launched with;
    a technique passes its own. Immediate compaction's output order depends on it (the groups),
    the alive set does not. `sources`: where the build finds cl/'s files (program.Sources; None: cl/).
    """

    def __init__(self, queue, local_size=program.LOCAL_SIZE, sources=None):
        self.queue = queue
        self.local_size = checked_local_size(local_size)
        self.program = program.build(queue, "compact.cl", {"LOCAL_SIZE": self.local_size}, directory=sources)
        # One kernel object each (every `program.name` access would create a new one).
        self._kernels = {name: cl.Kernel(self.program, name) for name in
                         ("scan_blocks", "scan_add_block_offsets", "compact_scatter", "compact_immediate")}
        self.last_stats = None
        self._launches = 0
        # Scratch memory kept for the compactor's life (a stream is compacted every iteration):
        # the atomic counter, the multi-pass offsets and the block sums of each scan level,
        # each grown to the largest stream seen.
        self._scratch = {}

    # -- public API -------------------------------------------------------------------------

    def compact_indices(self, alive_flags, n=None, method="immediate", out=None):
        """The indices i < n with alive_flags[i] != 0, on the device.

        `alive_flags` is a ``cl.Buffer`` of at least n int32 (0 = dead, else alive), a
        ``pyopencl.array.Array`` or a numpy array (any dtype; nonzero = alive; copied to the
        device as int32). `out`, if given, is a buffer of at least n int32 to reuse (a stream
        compacted every iteration should pass one: without it every call allocates its output;
        the compactor's own scratch memory is kept between calls).
        Returns ``(out_buffer, count)``: the first `count` ints of out_buffer are the indices
        (in order for "multipass", in unspecified work-group order for "immediate"). The
        buffer always holds room for max(n, 1) ints; n = 0 gives count 0.
        """
        if method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, not {method!r}")
        flags, n = self._device_flags(alive_flags, n)
        if n >= 2**31 - self.local_size:
            raise ValueError("streams are indexed with 32-bit ints: n must be below 2**31")
        if out is None:
            out = cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE, _INT * max(n, 1))
        elif out.size < _INT * n:
            raise ValueError(f"out holds {out.size // _INT} ints, the stream needs {n}")
        self._launches = 0
        if n == 0:
            count = 0
        elif method == "immediate":
            count = self._immediate(flags, n, out)
        else:
            count = self._multipass(flags, n, out)
        if not 0 <= count <= n:  # only a broken kernel or runtime gets here (e.g. a missing barrier)
            raise RuntimeError(f"{method} compaction counted {count} survivors among {n} items")
        self.last_stats = {"method": method, "n": n, "count": count,
                           "work_groups": -(-n // self.local_size), "launches": self._launches}
        return out, count

    def compact_on_device(self, alive_flags, n, out, method="multipass"):
        """compact_indices without reading the count back: `alive_flags` and `out` are buffers of at
        least n int32. Returns ``(out, count)``, `count` a one-int buffer on the device that holds the
        number of survivors until this compactor's next call: the kernels queued next read it (a
        launch over the whole stream whose work-items past the count return at once), or a copy
        keeps it, so the host never waits for it."""
        if method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, not {method!r}")
        flags, n = self._device_flags(alive_flags, n)
        if out.size < _INT * n:
            raise ValueError(f"out holds {out.size // _INT} ints, the stream needs {n}")
        if n == 0:
            raise ValueError("compact_on_device needs a stream of at least one item")
        self._launches = 0
        if method == "immediate":
            count = self._immediate_on_device(flags, n, out)
        else:
            count = self._multipass_on_device(flags, n, out)
        self.last_stats = {"method": method, "n": n, "count": None,
                           "work_groups": -(-n // self.local_size), "launches": self._launches}
        return out, count

    def reserve(self, n):
        """Allocate now the scratch memory that compacting or scanning streams of up to n items
        needs (else the first call of each larger size allocates it): a technique calls this
        when it makes its streams, so that no iteration allocates."""
        self._buffer("counter", 1)
        self._buffer("offsets", n)
        level, blocks = 0, -(-max(n, 1) // self.local_size)
        while True:
            self._buffer(("block_sums", level), blocks)
            if blocks == 1:
                return
            level, blocks = level + 1, -(-blocks // self.local_size)

    def compact_numpy(self, mask, method="immediate"):
        """Convenience for numpy: the compacted index array (int32) of a 1-D mask."""
        mask = np.asarray(mask).ravel()
        out, count = self.compact_indices(mask, len(mask), method)
        result = np.empty(count, np.int32)
        if count:
            cl.enqueue_copy(self.queue, result, out)  # blocking: reads only the first count ints
        return result

    def exclusive_scan(self, values, n, out=None):
        """Exclusive prefix sum of n int32 `values` (a cl.Buffer) into `out` (may be `values`).

        Returns ``(out_buffer, total)``. This is the scan of the multi-pass compaction, usable
        on its own (e.g. the talk's connection counts in parallel bidirectional connect).
        """
        if n == 0:
            return out if out is not None else cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE, _INT), 0
        out, total = self.exclusive_scan_on_device(values, n, out)
        return out, _read_int(self.queue, total)

    def exclusive_scan_on_device(self, values, n, out=None):
        """exclusive_scan without reading the total back: ``(out_buffer, total)``, `total` a one-int
        buffer on the device that holds it until this compactor's next call (n >= 1)."""
        if n < 1:
            raise ValueError("exclusive_scan_on_device needs at least one value")
        if out is None:
            out = cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE, _INT * n)
        return out, self._scan(values, out, n, as_flags=False)

    # -- the two methods ----------------------------------------------------------------------

    def _immediate(self, flags, n, out):
        return _read_int(self.queue, self._immediate_on_device(flags, n, out))

    def _immediate_on_device(self, flags, n, out):
        """One launch: each work-group reserves its survivors' places with one atomic; returns
        the one-int buffer that holds the count."""
        counter = self._buffer("counter", 1)
        cl.enqueue_fill_buffer(self.queue, counter, np.int32(0), 0, _INT)
        self._launch(self._kernels["compact_immediate"], n, flags, np.int32(n), counter, out)
        return counter

    def _multipass(self, flags, n, out):
        return _read_int(self.queue, self._multipass_on_device(flags, n, out))

    def _multipass_on_device(self, flags, n, out):
        """Scan and scatter; returns the one-int buffer that holds the count."""
        offsets = self._buffer("offsets", n)
        total = self._scan(flags, offsets, n, as_flags=True)
        self._launch(self._kernels["compact_scatter"], n, flags, np.int32(n), offsets, out)
        return total

    def _scan(self, src, dst, n, as_flags, level=0):
        """Exclusive scan src -> dst of n ints; returns a one-int buffer holding the total.

        Level 0 scans each work-group's slice and writes the group totals to block_sums; the
        block sums are scanned in place by the same code (recursively, local_size x fewer each level)
        and added back. When a level fits in one work-group its block sum is the total.
        """
        blocks = -(-n // self.local_size)
        block_sums = self._buffer(("block_sums", level), blocks)
        self._launch(self._kernels["scan_blocks"], n, src, np.int32(n), np.int32(as_flags), dst, block_sums)
        if blocks == 1:
            return block_sums
        total = self._scan(block_sums, block_sums, blocks, as_flags=False, level=level + 1)
        self._launch(self._kernels["scan_add_block_offsets"], n, dst, np.int32(n), block_sums)
        return total

    # -- helpers ----------------------------------------------------------------------------

    def _buffer(self, role, ints):
        """Scratch memory for `role` of at least `ints` int32, kept between calls (the queue is
        in order, so a call's kernels run after the previous call's are done with it)."""
        buffer = self._scratch.get(role)
        if buffer is None or buffer.size < _INT * ints:
            buffer = self._scratch[role] = cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE,
                                                     _INT * max(ints, 1))
        return buffer

    def _launch(self, kernel, n, *args):
        self._launches += 1
        program.launch(self.queue, kernel, n, *args, local_size=self.local_size)

    def _device_flags(self, alive_flags, n):
        """(cl.Buffer of int32 flags, n) for any accepted input."""
        if isinstance(alive_flags, cl.MemoryObjectHolder):
            if n is None:
                n = alive_flags.size // _INT
            if alive_flags.size < _INT * n:
                raise ValueError(f"the flag buffer holds {alive_flags.size // _INT} ints, n is {n}")
            return alive_flags, int(n)
        if isinstance(alive_flags, cl_array.Array):
            array = alive_flags
            if array.dtype != np.int32:
                array = (array != 0).astype(np.int32)  # also turns bool/uint8 into int flags
        else:
            host = np.asarray(alive_flags).ravel()
            array = host if host.dtype == np.int32 else (host != 0).astype(np.int32)
        if n is None:
            n = array.size
        if n > array.size:
            raise ValueError(f"the flag array holds {array.size} items, n is {n}")
        if n == 0:
            return None, 0
        if isinstance(array, np.ndarray):
            array = cl_array.to_device(self.queue, np.ascontiguousarray(array[:n]))
        return array.data, int(n)


def _read_int(queue, buffer):
    value = np.empty(1, np.int32)
    cl.enqueue_copy(queue, value, buffer)  # blocking copy: waits for the kernels before it
    return int(value[0])
