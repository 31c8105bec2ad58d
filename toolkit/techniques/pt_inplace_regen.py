"""Path tracing with in-place sample regeneration (Novak et al. 2010).

Kernel: cl/pt_inplace_regen.cl. Each work-item owns a slot. One iteration:
    extend     - every slot with a live path traces one more vertex;
    regenerate - every slot whose path ended starts the next sample of the budget in place.
Extension stays busy, but regeneration runs with only the terminated lanes active: the talk
measures ~30% active threads per warp in that step.

Option `stream_size`: the slots (default: the device's, toolkit/opencl/work_sizes.py: 32,768 on a CPU).
"""
import numpy as np
import pyopencl as cl

from toolkit.core.layout import PATH_STATE
from toolkit.opencl.work_sizes import checked_size
from toolkit.techniques.base import Technique


class PtInplaceRegen(Technique):
    name = "pt_inplace_regen"
    family = "pt"
    source = "pt_inplace_regen.cl"
    stream_size = None   # slots (work-items) that stay resident; None: the device's (toolkit/opencl/work_sizes.py)

    reads_every = 4      # iterations per blocking read of the "any path alive" flag (counters off)

    def __init__(self, *args, stream_size=None, **kwargs):
        checked_size("stream_size", stream_size)     # its range now, before the build; the device's memory after
        super().__init__(*args, **kwargs)
        self.stream_size = self.in_flight("stream_size", stream_size)

    def run_pass(self, film, camera, seed, sample_base, spp):
        budget = camera["width"] * camera["height"] * spp
        slots = min(self.stream_size, budget)
        capacity = np.int32(self.stream_capacity(slots))
        # Every buffer is made once per stream size and reused by every pass of the render.
        paths, lane_counts, regenerated, alive, next_sample, any_alive = self.reused(("slots", slots), lambda: (
            self.soa_buffer(PATH_STATE, slots), self.lane_counts_buffer(slots), self.int_buffer(slots),
            self.int_buffer(slots), self.int_buffer(1), self.int_buffer(1)))
        self.fill_ints(alive, 0)        # every slot free
        self.fill_ints(next_sample, 0)  # the pass's first sample comes next
        radiance = self.output_buffer(budget)
        # The host waits for the "any path alive" flag only every `reads_every` iterations: in
        # between, the GPU runs on. Once every path has ended, the iterations issued before the
        # next read find no work (every lane returns at once), so the image does not change.
        reads_every = 1 if self.count_simd else self.reads_every
        step = 0
        while True:
            # Regenerate: every free slot starts the next sample of the budget, if one is left.
            cl.enqueue_fill_buffer(self.queue, any_alive, np.int32(0), 0, 4)
            self.launch(self.kernel("pt_inplace_regen_regenerate"), slots, camera, seed,
                        np.int32(slots), np.int32(sample_base), np.int32(budget), next_sample, capacity,
                        paths, alive, any_alive, regenerated)
            self.count_regenerate(regenerated, slots)
            step += 1
            if step % reads_every == 0 and not self.read_ints(any_alive, 1)[0]:
                break   # budget spent and every path has ended
            # Extend: every slot with a live path traces one more vertex.
            self.launch(self.kernel("extend_in_place"), slots, *self.scene.args(), seed,
                        np.int32(slots), capacity, paths, alive, radiance, lane_counts)
            self.count_extend(lane_counts, slots, next_sample, budget)
        self.collect(film, radiance, budget)

    def count_regenerate(self, regenerated, slots):
        if self.count_simd:
            self.simd.add_stream_step("generate", self.read_ints(regenerated, slots) > 0)

    def count_extend(self, lane_counts, slots, next_sample, budget):
        """The extension step; once the sample counter has passed the budget, nothing regenerates
        any more and the step belongs to the final drain."""
        if self.count_simd:
            draining = self.read_ints(next_sample, 1)[0] >= budget
            self.count_stream_step(self.read_lane_counts(lane_counts, slots), capacity=slots, draining=draining)
