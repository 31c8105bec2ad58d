"""Path tracing with in-place sample regeneration (Novak et al. 2010).

Kernel: cl/pt_inplace_regen.cl. Each work-item owns a slot. One iteration:
    regenerate - every slot whose path ended starts the next sample of the budget in place;
    extend     - every slot with a live path traces one more vertex (trace, then shade).
Extension stays busy, but regeneration runs with only the terminated lanes active: the talk
measures ~30% active threads per warp in that step. A step is two launches: regeneration runs
at the start of the trace kernel (so the SIMD counters count it from its lanes, as before).

Option `stream_size`: the slots (default: the device's, toolkit/opencl/work_sizes.py: 32,768 on a CPU).
"""
from dataclasses import dataclass

import numpy as np
import pyopencl as cl

from toolkit.core.layout import HIT_RECORD, LANE_COUNTS, PATH_STATE, PT_PASS
from toolkit.opencl.work_sizes import checked_size
from toolkit.techniques.base import Technique, pixel_count
from toolkit.techniques.pass_end import PassEnd
from toolkit.techniques.device_memory import TurnBuffers
from toolkit.techniques.simd_recorder import StepTurns

# Steps whose SIMD counters one launch sums (a round, StepTurns): each step's lanes go to a turn of
# their own until then. 8: the counting launch is an eighth of a step's host time, for 8 copies of
# the lanes (slots x 20 bytes each: 43 MB at a GPU's 270,336 slots).
TURNS = 8


@dataclass
class SlotBuffers:
    """pt_inplace_regen's device memory: made once per stream size, reused by every pass."""
    paths: cl.Buffer         # PathState per slot, a structure of arrays of `capacity` records: the slot's path
    hits: cl.Buffer          # HitRecord per slot (the same layout): what its path's ray hit in this step
    lane_counts_turns: TurnBuffers   # LaneCounts per slot, per turn: what it did in an extension step (COUNT_SIMD)
    regenerated_turns: TurnBuffers   # int per slot, per turn: 1 where a regeneration started a sample (COUNT_SIMD)
    alive: cl.Buffer         # int per slot: 1 while it holds a live path, 0 while it is free
    next_sample: cl.Buffer   # one int: the next sample id of the pass to start (the slots' atomic counter)
    any_alive: cl.Buffer     # one int: set by every slot that holds a live path after a regeneration, cleared by shade
    radiance: cl.Buffer = None   # float4 per sample of the pass (DeviceMemory.output_buffer): set by each pass
    turn: int = 0            # which turn of the buffers above this step writes (the step's in its round)

    @property
    def lane_counts(self):
        return self.lane_counts_turns.by_turn[self.turn]

    @property
    def regenerated(self):
        return self.regenerated_turns.by_turn[self.turn]


class PtInplaceRegen(Technique):
    name = "pt_inplace_regen"
    family = "pt"
    source = "pt_inplace_regen.cl"

    reads_every = 8      # steps between the host's looks at the "any path alive" flag (counters off: pass_end.py)

    def __init__(self, *args, stream_size=None, **kwargs):
        checked_size("stream_size", stream_size)     # its range now, before the build; the device's memory after
        super().__init__(*args, **kwargs)
        # slots (work-items) that stay resident; None: the device's (toolkit/opencl/work_sizes.py)
        self.stream_size = self.size_in_flight("stream_size", stream_size)

    def slot_buffers(self, slots):
        """The device memory of `slots` slots (run_pass makes it once per stream size)."""
        m = self.memory
        return SlotBuffers(paths=m.soa_buffer(PATH_STATE, slots), hits=m.soa_buffer(HIT_RECORD, slots),
                           lane_counts_turns=m.turn_buffers(LANE_COUNTS.dtype.itemsize, slots, self.turns),
                           regenerated_turns=m.turn_buffers(4, slots, self.turns),
                           alive=m.int_buffer(slots), next_sample=m.int_buffer(1), any_alive=m.int_buffer(1))

    def run_pass(self, film, camera, seed, sample_base, spp):
        budget = pixel_count(camera) * spp
        slots = min(self.stream_size, budget)
        mem = self.memory.reused(("slots", slots), lambda: self.slot_buffers(slots))
        self.memory.fill_ints(mem.alive, 0)        # every slot free
        self.memory.fill_ints(mem.next_sample, 0)  # the pass's first sample comes next
        self.memory.fill_ints(mem.any_alive, 0)    # then each step's shade clears it for the next
        mem.radiance = self.memory.output_buffer(budget)
        pass_args = PT_PASS.record(seed=seed, sample_base=sample_base, budget=budget,
                                   capacity=self.memory.stream_capacity(slots))
        # The pass is over once no slot holds a live path after a regeneration; the host learns it
        # from a read behind the device (pass_end.py), so it never waits for the flag at a step.
        end = PassEnd(self.memory, np.int32, lambda any_alive: any_alive == 0, every=self.reads_every,
                      at_least=-(-budget // slots))
        mem.turn = 0
        counting = PassCount(budget, StepTurns(self.recorder, mem.lane_counts_turns, mem.regenerated_turns, stride=4,
                                               bound=slots, aux_bound=slots)) if self.count_simd else None
        k = self.kernels
        while True:
            # Regenerate: every free slot starts the next sample of the budget, if one is left;
            # then extend's first half, trace: every slot with a live path finds its ray's hit.
            # One launch for both: inside a render each launch costs the host tens of us.
            # (A kernel object per turn: each keeps its buffers set, program.kernel.)
            trace, shade = (k.kernel(name, copy=mem.turn) for name in ("pt_inplace_regen_trace", "pt_inplace_regen_shade"))
            k.launch(trace, slots, **k.scene_args(), cam=camera, pass_args=pass_args,
                     slots=k.int32(slots), next_sample=mem.next_sample, paths=mem.paths, alive=mem.alive,
                     hits=mem.hits, any_alive=mem.any_alive, regenerated=mem.regenerated, lane_counts=mem.lane_counts)
            # Looked at here, before shade clears it for the next step (the flag needs no host fill).
            if end.reached(mem.any_alive):
                break   # a regeneration some time ago left no live path: the steps since did nothing
            # Extend's second half, shade: each live path adds a vertex's light and goes on or ends.
            k.launch(shade, slots, **k.scene_args(), pass_args=pass_args, slots=k.int32(slots),
                     paths=mem.paths, alive=mem.alive, hits=mem.hits, radiance=mem.radiance,
                     any_alive=mem.any_alive, lane_counts=mem.lane_counts)
            if counting:
                self.count_extend(counting, slots)
                mem.turn = (mem.turn + 1) % self.turns   # the next step's counters go to the next turn
        if counting:
            counting.steps.close()
        self.collect(film, mem.radiance, budget)

    # --- SIMD counting, summed on the device (simd_recorder.py); no-op unless count_simd ----------

    @property
    def turns(self):
        """Turns of the counters' buffers: a round of steps counted by one launch, or 1 uncounted."""
        return TURNS if self.count_simd else 1

    def count_extend(self, counting, slots):
        """The extension step and the regeneration before it, summed on the device with the rest of
        their round (StepTurns): the extension's LaneCounts, and as the second buffer (aux) the
        slots that started a sample (PassCount.step)."""
        counting.steps.add(lambda recorder, sums: counting.step(recorder, sums, slots))


class PassCount:
    """The counters of one pass's steps, replayed in order (by each recorder that counts them): a
    regeneration, then the extension it feeds. Regeneration is numbered as the extension step that
    follows it; once the samples started so far (the regenerations' aux sums, added up) are the
    budget, it started the last samples or none and the steps belong to the final drain. (The same
    as the sample counter at the budget: a free slot raises the counter once, and starts a sample
    unless the budget is spent.) The first regeneration that leaves no live path (its extension
    step has no lane with work) ends the pass: it is counted, nothing after it (the host went on
    queueing steps until it learned so: pass_end.py)."""

    def __init__(self, budget, steps):
        self.budget = budget
        self.steps = steps          # the pass's steps, counted a round to a launch (StepTurns)
        self.ended = set()          # the recorders that have counted the pass's end
        self.started = {}           # by recorder: the samples the steps it counted started

    def step(self, recorder, sums, slots):
        """A regeneration (the aux ints: 1 where a slot started a sample) and the extension step after it."""
        if recorder in self.ended:
            return
        self.started[recorder] = started = self.started.get(recorder, 0) + sums.aux_sum()
        draining = started >= self.budget
        if sums.lanes is None:      # a row of the log: the same figures in fewer calls
            if not recorder.regeneration_row(sums.sums, slots, draining):
                self.ended.add(recorder)
            return
        recorder.mask_step("generate", sums, "aux", before=True, capacity=slots, draining=draining)
        if sums.work_lanes() == 0:
            self.ended.add(recorder)    # no slot holds a live path: budget spent and every path has ended
            return
        recorder.extension_step(sums, capacity=slots, draining=draining)
