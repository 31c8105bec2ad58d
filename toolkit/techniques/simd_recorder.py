"""A technique's SIMD counters (toolkit/core/simd.py): which lanes each step kept busy, and the
iteration each step belongs to, for the per-iteration plots. Off (count_simd=False), the
techniques skip the work that feeds it.

Summed on the device: a counting step queues the sums of its lanes into a step log
(toolkit/opencl/simd_counters.py) and a `replay` that turns that step's row into the counters'
figures; the log is read, and the replays run in the order the steps were taken, when someone
looks at the counters (the end of a render, a demo's frame) or the log is full. So the host never
waits for a step's lanes. `per_step` (the demo's lanes picture, which draws a few warps' lanes of
every step, and the tests' reference): each step's lanes are read back at once and counted on the
host, by the same PhaseCounter methods as before the log existed.
"""
import numpy as np
import pyopencl as cl

from toolkit.core.layout import LANE_COUNTS, SimdSum
from toolkit.core.simd import PhaseCounter
from toolkit.opencl import program
from toolkit.opencl.simd_counters import StepLog, StepSums


# The step log's sums (SimdSum) that a replay reads for a field of LaneCounts (or the aux ints):
# for a mask of lanes, its (active lanes, warps with one); for a loop in each lane, its (sum, sum of each warp's longest).
MASK_SUMS = {"work": (SimdSum.WORK_LANES, SimdSum.WORK_WARPS), "shadow_rays": (SimdSum.SHADOW_LANES, SimdSum.SHADOW_WARPS),
             "aux": (SimdSum.AUX_LANES, SimdSum.AUX_WARPS)}
LOOP_SUMS = {"work": (SimdSum.WORK_SUM, SimdSum.WORK_WARP_MAX), "aux": (SimdSum.AUX_SUM, SimdSum.AUX_WARP_MAX),
             "closest_steps": (SimdSum.CLOSEST_SUM, SimdSum.CLOSEST_WARP_MAX),
             "shadow_steps": (SimdSum.SHADOW_STEPS_SUM, SimdSum.SHADOW_STEPS_WARP_MAX)}


class SimdRecorder:
    def __init__(self, warp_width, on=True, queue=None, local_size=program.LOCAL_SIZE, sources=None):
        self.warp_width = warp_width
        self.on = bool(on)
        self.per_step = False       # read every step's lanes at once (a counter set as `simd`: the demo's)
        self._simd = PhaseCounter(warp_width)        # lanes busy per phase (extend, generate, connect, ...)
        self._traversal = PhaseCounter(warp_width)   # BVH traversal loops per warp (closest, shadow)
        self._counters = {}         # other PhaseCounters by name (the walk without compaction, ...)
        self.iterations = 0    # extension steps (loop iterations for pt_naive) over all passes so far
        self.queue, self.local_size, self.sources = queue, local_size, sources
        self._log = None            # the step log, made at the first counted step
        self._pending = []          # (row of the log or StepSums, replay) in the order of the steps
        self.reference = None       # a SimdRecorder in per-step mode given every step too (check_against_host)

    # --- what the counters say (read the log first) ------------------------------------------

    @property
    def simd(self):
        self.flush()
        return self._simd

    @simd.setter
    def simd(self, counter):
        """Count with `counter` from now on, fed step by step with the lanes read back at once: the
        demo's WarpSampler (toolkit/demo/lanes_picture.py) draws a few warps' lanes of every step."""
        self.flush()
        self._simd, self.per_step = counter, True

    @property
    def traversal(self):
        self.flush()
        return self._traversal

    def simd_counter(self):
        """The lanes-busy counter, for a replay (the log is being read: no flush)."""
        return self._simd

    def traversal_counter(self):
        """The traversal counter, for a replay."""
        return self._traversal

    def counter(self, name):
        """A PhaseCounter of its own (a figure for comparison: the walk without compaction, ...); a
        replay gets it as it is, a reader once the log has been read."""
        if name not in self._counters:
            self._counters[name] = PhaseCounter(self.warp_width)
        return self._counters[name]

    def efficiency(self):
        """SIMD efficiency per phase ({} when off)."""
        return self.simd.efficiency() if self.on else {}

    # --- queueing the steps -----------------------------------------------------------------

    def check_against_host(self):
        """Count every step a second time, as before the step log (lanes read back at once and summed
        by the host): into `reference`, a SimdRecorder of its own, whose figures must be the same."""
        self.reference = SimdRecorder(self.warp_width, self.on, self.queue, self.local_size, self.sources)
        self.reference.per_step = True
        return self.reference

    def later(self, replay):
        """A step whose figures the host knows (a count it launched over): replay(recorder) runs in order."""
        if self.reference is not None:
            self.reference.later(replay)
        self._pending.append((None, replay))
        if self.per_step:
            self.flush()

    def lanes(self, replay, lanes, stride, bound, length_at=None, length_index=-1, watch=None, watch_count=0,
              bins=0, slot_of=None, slot_offset=0, pool=0, packed=False, aux=None, aux_bound=0):
        """A step over the first `bound` lanes of `lanes` (a LaneCounts buffer, stride 4, or ints,
        stride 1), fewer if the device's int length_at[length_index] says so; `replay(sums)` gets its
        StepSums (toolkit/opencl/simd_counters.py StepLog.count says what each option adds)."""
        if self.reference is not None:
            self.reference.lanes(replay, lanes, stride, bound, length_at, length_index, watch, watch_count, bins,
                                 slot_of, slot_offset, pool, packed, aux, aux_bound)
        if self.per_step:
            self._pending.append((self._read_now(lanes, stride, bound, length_at, length_index, watch, watch_count,
                                                 slot_of, slot_offset, aux, aux_bound), replay))
            self.flush()
            return
        log = self._step_log()
        if log.full:
            self.flush()
        row = log.count(lanes, stride, bound, length_at, length_index, watch, watch_count, bins, slot_of,
                        slot_offset, pool, packed, aux, aux_bound)
        self._pending.append((row, replay))

    def lanes_two(self, first, second):
        """Two steps counted on the device by one launch (StepLog.count_two): `first` and `second`
        each (replay, lanes' keyword arguments: lanes=, stride=, bound=, ...; no bins, no packed),
        replayed in order. The BDPT walk's eye and light streams; a path tracer's steps (StepPairs)."""
        if self.reference is not None or self.per_step:
            for replay, step in (first, second):
                (self if self.per_step else self.reference).lanes(replay, **step)
            if self.per_step:
                return
        log = self._step_log()
        if not log.has_room(2):
            self.flush()
        rows = log.count_two(first[1], second[1])
        self._pending += [(rows[0], first[0]), (rows[1], second[0])]

    def lanes_turns(self, replays, lanes, aux, stride, bound, aux_bound):
        """A round's first len(replays) steps (StepTurns), step t's lanes in turn t of `lanes` and its
        aux ints in turn t of `aux` (TurnBuffers; `lanes`' arguments, the same for every step),
        counted by one launch (StepLog.count_turns) and replayed in order."""
        if self.reference is not None or self.per_step:
            for t, replay in enumerate(replays):
                (self if self.per_step else self.reference).lanes(replay, lanes.by_turn[t], stride, bound,
                                                                  aux=aux.by_turn[t], aux_bound=aux_bound)
            if self.per_step:
                return
        log = self._step_log()
        if not log.has_room(len(replays)):
            self.flush()
        first = 0
        while first < len(replays):      # one launch, unless the log holds fewer rows than a round
            if not log.has_room(1):
                self.flush()
            steps = min(len(replays) - first, log.room())
            row = log.count_turns(lanes.whole, aux.whole, first, steps, lanes.turn_lanes, stride, bound, aux_bound)
            self._pending += [(row + t, replays[first + t]) for t in range(steps)]
            first += steps

    def counted_by_kernels(self, replay, steps, pool):
        """`steps` steps whose kernels add their own lanes to the step log (StepLog.own_counts: the
        BDPT walk's streams, stamping the warps of a pool of `pool` samples), each replayed by
        `replay(sums)` in order with its row's sums, as `lanes`' steps are: each step's (log buffer,
        where its stamps are, row, stamp), or None in per-step mode, where the host reads each
        step's lanes instead (`lanes`). A reference recorder (check_against_host) is given the
        steps by the caller, once the kernels ran."""
        if self.per_step:
            return None
        log = self._step_log()
        if not log.has_room(steps) or not log.has_stamps(pool):
            self.flush()
        counts = log.own_counts(steps, pool)
        self._pending += [(count[2], replay) for count in counts]
        return counts

    def flush(self):
        """Read the step log and run the steps' replays, in order: replay(self[, the step's StepSums])."""
        if not self._pending:
            return
        pending, self._pending = self._pending, []
        rows = self._log.read() if self._log is not None else []
        for entry, replay in pending:
            if entry is None:
                replay(self)
            else:
                replay(self, rows[entry] if isinstance(entry, int) else entry)

    def step(self, phase, active, capacity=None, draining=False):
        """One step of the stream's loop (an extension, a walk step) over `active` lanes packed at
        the start of the launch (a count the host knows), numbered: `capacity` the stream's size
        (for the occupancy plot), `draining` whether no sample is left to start (the final drain)."""
        self.later(lambda r: r.count_now(phase, active, numbered=True, capacity=capacity, draining=draining))

    def before_step(self, phase, active, capacity=None, draining=False):
        """A step numbered as the step that follows it (a regeneration, counted with the
        extension it feeds), over `active` lanes packed at the start of the launch."""
        self.later(lambda r: r.count_now(phase, active, before=True, capacity=capacity, draining=draining))

    def loop(self, phase, iterations):
        """A loop that each work-item runs `iterations[k]` times (a host array): a warp issues it as
        long as its longest lane; its iterations are numbered from the steps so far, and count as steps."""
        sums = StepSums(lanes=_work(iterations))
        self.later(lambda r: (r.warp_loops(r.simd_counter(), phase, sums, "work"),
                              r.loop_iterations(phase, sums, numbered=True)))

    def inner_loop(self, phase, iterations):
        """A loop that each work-item of one launch runs `iterations[k]` times (a host array), between
        two steps (the naive connect phase: a lane's connections): a warp issues it as long as its
        longest lane; its iterations are numbered as the step that follows, as before_step's."""
        sums = StepSums(lanes=_work(iterations))
        self.later(lambda r: (r.warp_loops(r.simd_counter(), phase, sums, "work"),
                              r.loop_iterations(phase, sums, numbered=False)))

    def stream_step(self, phase, active):
        """A step over `active` lanes packed at the start of the launch, in the efficiency figures only."""
        self.later(lambda r: r.count_now(phase, active))

    # --- replaying a step: the same figures from the log's sums or from the lanes ---------------

    def count_now(self, phase, active, numbered=False, before=False, capacity=None, draining=False):
        """A step over `active` packed lanes, counted now (in a replay): numbered, or `before` the
        step that follows, or neither."""
        iteration = self.iterations if numbered or before else None
        self._simd.add_stream_step(phase, int(active), iteration=iteration, capacity=capacity, draining=draining)
        if numbered:
            self.iterations += 1


    def walk_row(self, row, pool, draining, uncompacted):
        """A BDPT walk step's replay from its row of the log (a list of ints by SimdSum), the walk
        without compaction into the counter named `uncompacted`: what
        BdptEvaluator.walk_replay adds from the lanes (count_now, the compaction, warp_loops of
        the traversal, slot_warps), the same integers in fewer calls, since a render replays
        thousands of them (tests/test_simd_device.py compares the two)."""
        length = row[SimdSum.LANES]
        if length == 0:
            return      # a stream the device had found empty
        w = self.warp_width
        issued = -(-length // w) * w
        self._simd.add_step("walk", length, issued, self.iterations, pool, draining)
        self.iterations += 1
        self._simd.add("compact", length, issued)
        self._traversal.add("closest", row[SimdSum.CLOSEST_SUM], row[SimdSum.CLOSEST_WARP_MAX] * w)
        self.counter(uncompacted).add("walk", length, row[SimdSum.SLOT_WARPS] * w)

    def regeneration_row(self, row, capacity, draining):
        """A pt_inplace_regen step's replay from its row of the log (a list of ints by SimdSum): the
        regeneration (its aux lanes, numbered as the extension after it) and, if any lane had work,
        the extension step; the integers mask_step and extension_step add from the same sums, in
        fewer calls, since a render replays hundreds of them (tests/test_simd_device.py compares the
        two). Returns whether the extension had work (none: the pass has ended)."""
        w, simd, traversal, iteration = self.warp_width, self._simd, self._traversal, self.iterations
        simd.add_step("generate", row[SimdSum.AUX_LANES], row[SimdSum.AUX_WARPS] * w, iteration, capacity, draining)
        if row[SimdSum.WORK_LANES] == 0:
            return False
        simd.add_step("extend", row[SimdSum.WORK_LANES], row[SimdSum.WORK_WARPS] * w, iteration, capacity, draining)
        self.iterations = iteration + 1
        traversal.add("closest", row[SimdSum.CLOSEST_SUM], row[SimdSum.CLOSEST_WARP_MAX] * w)
        simd.add("shadow", row[SimdSum.SHADOW_LANES], row[SimdSum.SHADOW_WARPS] * w)
        traversal.add("shadow", row[SimdSum.SHADOW_STEPS_SUM], row[SimdSum.SHADOW_STEPS_WARP_MAX] * w)
        return True

    def mask_step(self, phase, sums, field="work", numbered=False, before=False, capacity=None, draining=False,
                  counter=None):
        """A step whose active lanes are those with `field` > 0 (work, shadow_rays, or the aux ints): numbered (an
        extension step, counted as an iteration), `before` (numbered as the step that follows it),
        or neither (efficiency figures only)."""
        counter = self._simd if counter is None else counter
        iteration = self.iterations if numbered or before else None
        if sums.lanes is not None:
            values = _values(sums, field)
            counter.add_stream_step(phase, values > 0, iteration=iteration, capacity=capacity, draining=draining)
        else:
            lanes, warps = MASK_SUMS[field]
            counter.add_step(phase, sums[lanes], sums[warps] * self.warp_width, iteration, capacity, draining)
        if numbered:
            self.iterations += 1

    def extension_step(self, sums, capacity, draining=False, shadow_queue=False):
        """SIMD counters of one extension step over a stream, from the LaneCounts of the lanes
        that ran it; with `shadow_queue` the shadow rays are traced (and counted) by a kernel
        of their own, else inside the step."""
        self.mask_step("extend", sums, "work", numbered=True, capacity=capacity, draining=draining)
        self.warp_loops(self._traversal, "closest", sums, "closest_steps")
        if not shadow_queue:
            self.mask_step("shadow", sums, "shadow_rays")
            self.warp_loops(self._traversal, "shadow", sums, "shadow_steps")

    def warp_loops(self, counter, phase, sums, field, active=None):
        """A loop inside each lane that runs `field` times (work, closest_steps, shadow_steps): its
        warp issues it as long as its longest lane. `active`: another lane-step count (a SimdSum)."""
        if sums.lanes is not None:
            counter.add_warp_loops(phase, _values(sums, field), None if active is None else sums.lanes[active].sum())
            return
        total, longest = LOOP_SUMS[field]
        active_sum = total if active is None else {"shadow_rays": SimdSum.SHADOW_SUM}[active]
        counter.add(phase, sums[active_sum], sums[longest] * self.warp_width)

    def loop_iterations(self, phase, sums, numbered):
        """The per-iteration figures of the `work` loop inside each lane, numbered from the steps so
        far; `numbered`: its iterations count as steps (pt_naive's whole path), else they are
        numbered as the step that follows (the naive connect phase)."""
        first = self.iterations
        if sums.lanes is not None:
            work = sums.lanes["work"]
            self._simd.add_loop_iterations(phase, work, first_iteration=first)
            longest = int(work.max()) if len(work) else 0
        else:
            self._simd.add_loop_histogram(phase, sums.histogram, sums[SimdSum.LANES], first_iteration=first)
            longest = sums[SimdSum.WORK_MAX]
        if numbered:
            self.iterations += longest

    def slot_warps(self, counter, phase, sums, pool):
        """The lanes' samples in the slots of a pool of `pool` (without compaction each keeps its
        slot's lane): active lanes = the lanes, issued = the pool's warps that hold one of them."""
        if sums.slots is not None:
            mask = np.zeros(pool, bool)
            mask[sums.slots] = True
            counter.add_stream_step(phase, mask)
        else:
            counter.add(phase, sums[SimdSum.LANES], sums[SimdSum.SLOT_WARPS] * self.warp_width)

    def packed_loops(self, counter, phase, sums):
        """The `work` loop with only the lanes that have work, packed side by side."""
        if sums.lanes is not None:
            work = sums.lanes["work"]
            counter.add_warp_loops(phase, work[work > 0])
        else:
            counter.add(phase, sums[SimdSum.WORK_SUM], sums[SimdSum.PACKED_WARP_MAX] * self.warp_width)

    # --- per-step mode and the log ------------------------------------------------------------

    def _read_now(self, lanes, stride, bound, length_at, length_index, watch, watch_count, slot_of, slot_offset,
                  aux, aux_bound):
        """The step's lanes (and watched ints, slots, aux) read back at once: a StepSums for the host's sums."""
        n = bound
        if length_at is not None and length_index >= 0:
            n = min(n, int(_read(self.queue, length_at, np.int32, length_index + 1)[length_index]))
        n = max(n, 0)
        aux_values = _read(self.queue, aux, np.int32, max(aux_bound, 0)) if aux is not None else None
        values = _read(self.queue, lanes, np.int32 if stride == 1 else LANE_COUNTS.dtype, n)
        watched = _read(self.queue, watch, np.int32, watch_count) if watch_count else None
        slots = _read(self.queue, slot_of, np.int32, n, 4 * slot_offset) if slot_of is not None else None
        sums = np.zeros(int(SimdSum.FIELDS), np.int64)
        sums[SimdSum.LANES] = n
        return StepSums(sums=sums, lanes=values, slots=slots, watch=watched, aux=aux_values)

    def _step_log(self):
        if self._log is None:
            self._log = StepLog(self.queue, self.warp_width, self.local_size, self.sources)
        return self._log


def _read(queue, buffer, dtype, n, offset=0):
    out = np.zeros(n, dtype)
    if n:
        cl.enqueue_copy(queue, out, buffer, src_offset=offset)
    return out



def _work(iterations):
    """Per-lane loop counts from the host as LaneCounts (work only), for the replays."""
    out = LANE_COUNTS.zeros(len(iterations))
    out["work"] = iterations
    return out


def _values(sums, field):
    """Per-step mode: the read lanes' `field` (LaneCounts), the ints of an int buffer, or the aux ints."""
    if field == "aux":
        return sums.aux
    return sums.lanes if sums.lanes.dtype.names is None else sums.lanes[field]


class StepTurns:
    """A pass's steps counted a round to a launch: step t of a round writes its lanes to turn t of
    buffers that hold a round's steps (TurnBuffers: `lanes`, and `aux` for the ints a step's other
    kernel writes), `add(replay)` holds the step, and the round's last step queues the round
    (SimdRecorder.lanes_turns); `close()`, at the pass's end, queues the steps still held. A pass
    starts at turn 0. A held step's lanes are intact until the next round writes its turn, which
    the queue runs after the round's count. Counted one to a launch, a path tracer's step costs
    the host about as much as its two kernels; two to a launch (StepPairs), still half that."""

    def __init__(self, recorder, lanes, aux, stride, bound, aux_bound):
        self.recorder, self.lanes, self.aux = recorder, lanes, aux
        self.step = dict(stride=stride, bound=bound, aux_bound=aux_bound)
        self.held = []

    def add(self, replay):
        self.held.append(replay)
        if len(self.held) == self.lanes.turns:
            self.close()

    def close(self):
        if self.held:
            held, self.held = self.held, []
            self.recorder.lanes_turns(held, self.lanes, self.aux, **self.step)


class StepPairs:
    """A pass's steps counted two to a launch: `lanes(replay, **step)` holds a step until the next
    one comes, then queues both (SimdRecorder.lanes_two); `close()`, at the pass's end, queues a
    step still held, alone. For a technique whose step kernels write each step's lanes (and what
    the step watches) to the other of two buffers than the step before: a held step's are then
    intact until the step after next is queued. A counted step of a path tracer is one launch of
    its own otherwise, about as much host time as the step's two kernels."""

    def __init__(self, recorder):
        self.recorder, self.held = recorder, None

    def lanes(self, replay, **step):
        if self.held is None:
            self.held = (replay, step)
            return
        first, self.held = self.held, None
        self.recorder.lanes_two(first, (replay, step))

    def close(self):
        if self.held is not None:
            (replay, step), self.held = self.held, None
            self.recorder.lanes(replay, **step)
