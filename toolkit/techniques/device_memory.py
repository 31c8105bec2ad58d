"""A technique's device memory: buffers sized in whole work-groups, memory kept from pass to
pass, and reading results back to the host."""
from dataclasses import dataclass

import numpy as np
import pyopencl as cl

from toolkit.core.layout import LANE_COUNTS
from toolkit.opencl import program


class DeviceMemory:
    def __init__(self, queue, local_size):
        self.queue = queue
        self.local_size = local_size
        self._reused = {}

    def padded(self, n):
        """n rounded up to a multiple of the local size (a launch's global size)."""
        return program.padded(n, self.local_size)

    def reused(self, key, make):
        """Device memory that keeps its size from pass to pass (streams, vertex memory) is made
        once: `key` names it with its size, `make()` allocates it."""
        if key not in self._reused:
            self._reused[key] = make()
        return self._reused[key]

    def output_buffer(self, n):
        """One float4 per sample of the pass, pre-filled with .w = -1 ("not written yet"); made
        once, at the largest pass's size (a render's first pass: only its last is smaller), and
        refilled by every pass (the in-order queue runs collect's sums of it first)."""
        buf = self._reused.get("output")
        if buf is None or buf.size < 16 * self.padded(n):
            buf = self._reused["output"] = cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE, 16 * self.padded(n))
        cl.enqueue_fill_buffer(self.queue, buf, np.array([0, 0, 0, -1], np.float32), 0, 16 * self.padded(n))
        return buf

    def int_buffer(self, n, fill=None):
        buf = cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE, 4 * max(1, self.padded(n)))
        if fill is not None:
            self.fill_ints(buf, fill)
        return buf

    def fill_ints(self, buffer, value):
        """Set every int of `buffer` to `value` (on the device, queued)."""
        cl.enqueue_fill_buffer(self.queue, buffer, np.int32(value), 0, buffer.size)

    def lane_counts_buffer(self, n):
        """One LaneCounts record per work-item (toolkit/core/layout.py), written when COUNT_SIMD and summed
        on the device (toolkit/opencl/simd_counters.py): the host never reads it back whole."""
        return cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE,
                         LANE_COUNTS.dtype.itemsize * self.padded(max(n, 1)))

    def turn_buffers(self, itemsize, n, turns):
        """`turns` buffers of n items of `itemsize` bytes (4: ints, 16: LaneCounts), a step's in turn,
        as sub-buffers of one (TurnBuffers), so that one launch reads a round of steps
        (cl/simd_counters.cl simd_count_turns). Turns are `turn_lanes` items apart, a multiple of
        the device's base address alignment for ints and LaneCounts alike. One turn: one buffer."""
        lanes = self.padded(max(n, 1))
        if turns == 1:
            whole = cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE, itemsize * lanes)
            return TurnBuffers(whole, (whole,), lanes)
        align_ints = max(1, self.queue.device.mem_base_addr_align // 32)   # bits, in 4-byte ints
        turn_lanes = -(-lanes // align_ints) * align_ints
        whole = cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE, itemsize * turn_lanes * turns)
        by_turn = tuple(whole.get_sub_region(itemsize * turn_lanes * t, itemsize * lanes) for t in range(turns))
        return TurnBuffers(whole, by_turn, turn_lanes)

    def record_buffer(self, record):
        """One record of layout `record` (toolkit/core/layout.py) on the device: counts the kernels keep."""
        return cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE, record.dtype.itemsize)

    def soa_buffer(self, record, n):
        """A stream of n records as a structure of arrays in one buffer; its capacity (what the
        kernels take with it) is n padded to the local size: see stream_capacity()."""
        return record.soa_buffer(self.queue.context, self.stream_capacity(n))

    def stream_capacity(self, n):
        return self.padded(n)

    def read_structs(self, record, buffer, n, offset=0):
        """n records of layout `record` from `buffer` (starting `offset` bytes in)."""
        out = record.zeros(n)
        if n:
            cl.enqueue_copy(self.queue, out, buffer, src_offset=offset)
        return out

    def read_later(self, buffer, dtype):
        """One value of `dtype` (a numpy dtype, or a record's) from the start of `buffer`, read behind
        the kernels queued so far without waiting for them: a PendingRead, whose result() waits
        when the host needs it."""
        return PendingRead(self.queue, np.zeros(1, dtype), buffer)

    def read_ints(self, buffer, n, columns=1):
        out = np.empty((n, columns) if columns > 1 else n, np.int32)
        if n:
            cl.enqueue_copy(self.queue, out, buffer)
        return out


class PendingRead:
    """A read queued behind the kernels before it that the host has not waited for yet: it goes on
    queueing work, and waits (result()) only when it needs the values, by which time a device that
    runs behind the host has long done it."""

    def __init__(self, queue, out, buffer):
        self.out = out
        self.event = cl.enqueue_copy(queue, out, buffer, is_blocking=False)

    def result(self):
        self.event.wait()
        return self.out[0]


@dataclass
class TurnBuffers:
    """DeviceMemory.turn_buffers: one buffer, and the sub-buffers of its turns, `turn_lanes` items apart."""
    whole: cl.Buffer
    by_turn: tuple
    turn_lanes: int

    @property
    def turns(self):
        return len(self.by_turn)
