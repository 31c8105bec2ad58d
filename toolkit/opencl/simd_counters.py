"""The SIMD counters summed on the device (host side of cl/simd_counters.cl): each counting step's
LaneCounts added up into one row of a step log (SimdSum, toolkit/core/layout.py), read back once
per pass or per frame instead of every lane after every step.

Why: with the counters read per step, a counted render cost the host 1.9 to 7.5 times an uncounted
one (a blocking read per step, then numpy over every lane). Queued here, a step costs one launch;
the rows are integers, so the host's sums of them are the sums it made of the lanes before.
"""
from dataclasses import dataclass

import numpy as np
import pyopencl as cl

from toolkit.core.layout import SIMD_STEP, SimdSum
from toolkit.opencl import program

ROWS = 1024            # steps the log holds before the host reads it (a pass rarely takes more)
HISTOGRAM_ROWS = 64    # loops with a per-iteration histogram the log holds (one per pt_naive pass, naive connect phase)
COPIES = 4             # kernel objects per counting kernel, one per set of buffers that take turns (StepLog._kernel)


@dataclass
class StepSums:
    """One counted step, once the log has been read: `sums[SimdSum.X]` as Python ints; `histogram`
    (lanes, warps) by work, for a loop counted with one; `lanes` etc. only where the host read the
    lanes themselves (SimdRecorder's per-step mode)."""
    sums: list = None                # int per SimdSum field (a Python list: a replay indexes it many times)
    histogram: np.ndarray = None     # (bins, 2): lanes, warps by work (warps: by their largest work)
    lanes: np.ndarray = None         # the host's copy of the lanes (per-step mode): LaneCounts or ints
    slots: np.ndarray = None         # per-step mode: each lane's sample slot
    watch: np.ndarray = None         # per-step mode: the watched ints
    aux: np.ndarray = None           # per-step mode: the second buffer's ints

    def __getitem__(self, field):
        return int(self.sums[field])

    def work_lanes(self):
        """Lanes with work > 0."""
        if self.lanes is not None:
            work = self.lanes if self.lanes.dtype.names is None else self.lanes["work"]
            return int(np.count_nonzero(work > 0))
        return self[SimdSum.WORK_LANES]

    def aux_sum(self):
        """The sum of the second buffer's ints (AUX_SUM)."""
        if self.aux is not None:
            return int(self.aux.sum())
        return self[SimdSum.AUX_SUM]

    def watched(self, k=0):
        """The k-th int copied from the device when the step was counted."""
        if self.watch is not None:
            return int(self.watch[k])
        word = int(self.sums[SimdSum.WATCH + k]) & 0xffffffff    # the int32 it was, from its 64-bit row
        return word - (1 << 32) if word >= 1 << 31 else word


class StepLog:
    """The step log on `queue`'s device: `count(...)` queues one step's sums into the next row and
    returns its index; `read()` reads the rows queued so far (and their histograms) and empties it."""

    def __init__(self, queue, warp_width, local_size=program.LOCAL_SIZE, sources=None):
        self.queue, self.warp_width, self.local_size = queue, int(warp_width), local_size
        self.built = program.build(queue, "simd_counters.cl", {"LOCAL_SIZE": local_size}, directory=sources)
        self.packed_kernel = program.kernel(self.built, "simd_count_packed")
        self.turns_kernel = program.kernel(self.built, "simd_count_turns")
        self._ints = {}                        # np.int32 by value (ints)
        self.copy_of = {}                      # (kernel name, its buffers' ids) -> the kernel object's copy (_kernel)
        self.row_bytes = 8 * int(SimdSum.FIELDS)
        self.rows = self.none = None           # the log, and an argument no work-item reads: at the first step
        self.rows_bytes = self.stamp_words = 0  # the rows' bytes in it, and the pool warps' stamps after them (own_counts)
        self.used = 0                          # rows queued since the last read
        self.histogram, self.bins, self.histogram_used = None, 0, []   # [(row, bins)] queued with a histogram
        self.made, self.stamp = {}, 0          # buffers made once (pool warps' stamps, scratch) and the last stamp given
        self.records = {}                      # SimdStep records made (_step)

    @property
    def full(self):
        return self.used == ROWS or len(self.histogram_used) == HISTOGRAM_ROWS

    def has_room(self, rows):
        """Whether `rows` more steps fit before the log must be read."""
        return self.used + rows <= ROWS and len(self.histogram_used) < HISTOGRAM_ROWS

    def count(self, lanes, stride, bound, length_at=None, length_index=-1, watch=None, watch_count=0,
              bins=0, slot_of=None, slot_offset=0, pool=0, packed=False, aux=None, aux_bound=0):
        """Queue the sums of one step's lanes (cl/simd_counters.cl simd_count_lanes): the first `bound`
        lanes of `lanes` (`stride` ints each), fewer if length_at[length_index] on the device says so.
        `watch`: a buffer whose first `watch_count` ints the row keeps. `bins`: a per-iteration
        histogram of the lanes' work (0 .. bins - 1). `slot_of`, `slot_offset`, `pool`: lane i's
        slot (int slot_offset + i of slot_of) in a pool of `pool` samples (SLOT_WARPS). `packed`: also
        PACKED_WARP_MAX (its lanes are all `bound`, none past a device length). `aux`: a second
        buffer of one int per lane, its first `aux_bound` into AUX_. Returns the row."""
        if self.full:
            raise RuntimeError("the step log is full: read it first")
        self._rows()
        row = self.used
        self.used += 1
        histogram_row = self._histogram_column(row, bins) if bins else -1
        (lanes, length_at, watch, slot_of, stamps, aux), step, warps, stamp = self._queued(
            lanes, stride, bound, length_at, length_index, watch, watch_count, slot_of, slot_offset, pool,
            aux, aux_bound, histogram_row)
        buffers = (lanes, length_at, self.rows, watch, self.histogram if bins else self.none, slot_of, stamps, aux)
        program.launch(self.queue, self._kernel("simd_count_lanes", buffers), warps, *buffers, step, np.int32(row),
                       np.int32(stamp), local_size=self.local_size)
        if packed:   # one work-group (cl/simd_counters.cl simd_count_packed)
            program.launch(self.queue, self.packed_kernel, 1, lanes, np.int32(stride), np.int32(bound),
                           np.int32(self.warp_width), self.rows, np.int32(row), local_size=self.local_size)
        return row

    def count_two(self, first, second):
        """Queue two steps with one launch (cl/simd_counters.cl simd_count_two_steps): `first` and
        `second` each count's keyword arguments (lanes, stride, bound, ...) but bins and packed. The
        BDPT walk's eye and light streams, or a path tracer's two consecutive steps. The same rows
        as two calls of count; returns them."""
        if not self.has_room(2):
            raise RuntimeError("the step log is full: read it first")
        self._rows()
        buffers, steps, warps, stamps = [self.rows], [], [], []
        for k, step in enumerate((first, second)):
            b, record, n, stamp = self._queued(second=k == 1, **step)
            buffers[-1:-1] = b       # each step's buffers, then the log's rows
            steps.append(record)
            warps.append(n)
            stamps.append(np.int32(stamp))
        row = self.used
        self.used += 2
        program.launch(self.queue, self._kernel("simd_count_two_steps", buffers), warps[0] + warps[1], *buffers,
                       np.int32(row), *stamps, np.int32(warps[0]), *steps, local_size=self.local_size)
        return row, row + 1

    def count_turns(self, lanes, aux, first_turn, steps, turn_lanes, stride, bound, aux_bound):
        """Queue `steps` steps with one launch (cl/simd_counters.cl simd_count_turns), turns first_turn,
        first_turn + 1, ...: turn t's first `bound` lanes (`stride` ints each) start at lane
        t * turn_lanes of `lanes`, its first `aux_bound` aux ints at t * turn_lanes of `aux` (count's
        aux). Rows in order, as `steps` calls of count would give them; returns the first."""
        if not self.has_room(steps):
            raise RuntimeError("the step log is full: read it first")
        self._rows()
        row = self.used
        self.used += steps
        warps = max(1, -(-max(bound, aux_bound) // self.warp_width))
        ints = self.ints
        program.launch(self.queue, self.turns_kernel, steps * warps, lanes, aux, self.rows, np.int32(row),
                       ints(first_turn), ints(steps), ints(warps), ints(turn_lanes),
                       self._step(stride, bound, -1, aux_bound=aux_bound), local_size=self.local_size)
        return row

    def room(self):
        """Steps that fit before the log must be read (has_room)."""
        return ROWS - self.used if len(self.histogram_used) < HISTOGRAM_ROWS else 0

    def ints(self, value):
        """np.int32(value), one object per value: a launch that gives the same object again sets nothing."""
        made = self._ints.get(value)
        if made is None:
            if len(self._ints) >= 256:
                self._ints.clear()
            made = self._ints[value] = np.int32(value)
        return made

    def has_stamps(self, pool):
        """Whether the log's buffer holds the stamps of a pool of `pool` samples' warps (own_counts)."""
        return self.rows is not None and self.stamp_words >= self._pool_warps(pool)

    def own_counts(self, rows, pool):
        """Rows for `rows` steps whose kernels add their own lanes to the log (the BDPT walk's
        bdpt_extend: cl/simd_counters.h simd_count_group), in order, each with a stamp of its own for
        the warps of a pool of `pool` samples (SLOT_WARPS): [(the log's buffer, where in it (uints)
        the pool warps' stamps are, row, stamp)]. The stamps live in the log's buffer after its rows
        (a kernel has few arguments to spare); a larger pool makes the buffer anew, so the log must
        be empty then (read it first: has_stamps). The steps run one after the other (an in-order
        queue), so they share the stamps."""
        if not self.has_room(rows):
            raise RuntimeError("the step log is full: read it first")
        self._rows()
        if not self.has_stamps(pool):
            if self.used:
                raise RuntimeError("the step log must be read before it is made for a larger pool")
            self._make_rows(self._pool_warps(pool))
        stamps_at = self.rows_bytes // 4
        out = []
        for _ in range(rows):
            self.stamp += 1
            out.append((self.rows, stamps_at, self.used, self.stamp))
            self.used += 1
        return out

    def _pool_warps(self, pool):
        return max(1, -(-pool // self.warp_width))

    def _queued(self, lanes, stride, bound, length_at=None, length_index=-1, watch=None, watch_count=0,
                slot_of=None, slot_offset=0, pool=0, aux=None, aux_bound=0, histogram_row=-1, second=False):
        """One step's buffers as its kernel takes them (lanes, length_at, watch, slot_of, warp
        stamps, aux: an argument no work-item reads where there is none), its SimdStep record, its
        warps (the work-items it needs) and its stamp (0: none). `second`: the second step of a
        launch (its own stamps)."""
        stamp = 0
        if slot_of is not None:
            self.stamp += 1
            stamp = self.stamp
        none = self.none
        step = self._step(stride, bound, length_index, watch_count, histogram_row, slot_offset,
                          aux_bound if aux is not None else 0)
        buffers = (lanes, none if length_at is None else length_at, none if watch is None else watch,
                   none if slot_of is None else slot_of, self._stamps(pool, second) if slot_of is not None else none,
                   none if aux is None else aux)
        return buffers, step, max(1, -(-max(bound, aux_bound) // self.warp_width)), stamp

    def _kernel(self, name, buffers):
        """The kernel `name`, one object per set of buffers a loop takes turns with (program.kernel's
        copies; at most COPIES of each): a launch of a stream's step, whose buffers swap every step,
        then sets only the step's row and stamp, not its buffers (program.launch)."""
        key = (name, *map(id, buffers))
        if key not in self.copy_of:
            if len(self.copy_of) >= 64:    # ids of buffers long freed
                self.copy_of.clear()
            self.copy_of[key] = sum(k[0] == name for k in self.copy_of) % COPIES
        return program.kernel(self.built, name, copy=self.copy_of[key])

    def _rows(self):
        """The log's buffers, made at the first step."""
        if self.rows is None:
            self.none = cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE, 4)
            self._make_rows(0)

    def _make_rows(self, stamp_words):
        """The log's buffer: ROWS rows, then `stamp_words` pool warps' stamps (own_counts), all zero."""
        self.rows_bytes = self.row_bytes * ROWS
        size = self.rows_bytes + 4 * stamp_words
        self.rows = cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE, size)
        cl.enqueue_fill_buffer(self.queue, self.rows, np.uint32(0), 0, size)
        self.stamp_words = stamp_words

    def _step(self, stride, bound, length_index, watch_count=0, histogram_row=-1, slot_offset=0, aux_bound=0):
        """The SimdStep record of a counted step (its fields: layout.py SIMD_STEP), made once for the
        steps that share it (a loop's steps differ in their row and stamp only, arguments of their
        own): the same read-only object, which a launch knows without setting it again (program.launch)."""
        key = (stride, bound, length_index, watch_count, histogram_row, slot_offset, aux_bound, self.bins)
        record = self.records.get(key)
        if record is None:
            if len(self.records) >= 256:    # bounds that change from pass to pass
                self.records.clear()
            record = self.records[key] = SIMD_STEP.record(
                stride=stride, bound=bound, length_index=length_index, warp_width=self.warp_width,
                watch_count=watch_count, bins=max(self.bins, 1), histogram_row=histogram_row,
                histogram_rows=HISTOGRAM_ROWS, slot_offset=slot_offset, aux_bound=aux_bound)
        return record

    def read(self):
        """The rows queued since the last read, as StepSums in order (one blocking read, two with
        histograms); the log is emptied for the next steps."""
        if self.used == 0:
            return []
        words = np.empty((self.used, int(SimdSum.FIELDS), 2), np.uint32)
        cl.enqueue_copy(self.queue, words, self.rows)
        sums = words[..., 0].astype(np.int64) | (words[..., 1].astype(np.int64) << 32)
        out = [StepSums(sums=s) for s in sums.tolist()]
        if self.histogram_used:
            needed = max(int(out[row][SimdSum.WORK_MAX]) for row, _ in self.histogram_used) + 1
            for row, bins in self.histogram_used:
                if out[row][SimdSum.WORK_MAX] >= bins:
                    raise RuntimeError(f"a lane's loop ran {out[row][SimdSum.WORK_MAX]} times, past the "
                                       f"{bins - 1} its histogram holds")
            counts = np.empty((needed, 2, HISTOGRAM_ROWS), np.uint32)
            cl.enqueue_copy(self.queue, counts, self.histogram)
            for column, (row, _) in enumerate(self.histogram_used):
                out[row].histogram = counts[:, :, column].astype(np.int64)
            cl.enqueue_fill_buffer(self.queue, self.histogram, np.uint32(0), 0, self.histogram.size)
            self.histogram_used = []
        cl.enqueue_fill_buffer(self.queue, self.rows, np.uint32(0), 0, self.row_bytes * self.used)
        self.used = 0
        return out

    # --- device memory, made once ---------------------------------------------------------------

    def _histogram_column(self, row, bins):
        if self.histogram is None or bins > self.bins:
            if self.histogram_used:
                raise RuntimeError("a larger histogram while one is in use: read the log first")
            self.bins = bins
            size = 4 * bins * 2 * HISTOGRAM_ROWS
            self.histogram = cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE, size)
            cl.enqueue_fill_buffer(self.queue, self.histogram, np.uint32(0), 0, size)
        self.histogram_used.append((row, bins))
        return len(self.histogram_used) - 1

    def _stamps(self, pool, second=False):
        """The pool warps' stamps; `second`: another set, for the second of two steps counted at once
        (stamps only grow, so a step may use either set, but two steps at once must not share one)."""
        warps = max(1, -(-pool // self.warp_width))
        key = ("stamps", warps, second)
        if key not in self.made:
            self.made[key] = cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE, 4 * warps)
            cl.enqueue_fill_buffer(self.queue, self.made[key], np.int32(0), 0, 4 * warps)
        return self.made[key]


