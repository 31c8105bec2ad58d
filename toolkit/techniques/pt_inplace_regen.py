"""Path tracing with in-place sample regeneration (Novak et al. 2010).

Kernel: cl/pt_inplace_regen.cl. Each work-item owns a slot. One iteration:
    extend     - every slot with a live path traces one more vertex;
    regenerate - every slot whose path ended starts the next sample of the budget in place.
Extension stays busy, but regeneration runs with only the terminated lanes active: the talk
measures ~30% active threads per warp in that step.
"""
import numpy as np
import pyopencl as cl

from .. import program
from ..layout import PATH_STATE
from .base import Technique


class PtInplaceRegen(Technique):
    name = "pt_inplace_regen"
    source = "pt_inplace_regen.cl"
    stream_size = 1 << 15   # slots (work-items) that stay resident

    def run_pass(self, film, camera, seed, sample_base, spp):
        budget = camera["width"] * camera["height"] * spp
        slots = min(self.stream_size, budget)
        paths, lane_counts, regenerated = self.reused(("slots", slots), lambda: (
            PATH_STATE.soa_buffers(self.queue.context, slots), self.lane_counts_buffer(slots),
            self.int_buffer(slots)))
        alive = self.int_buffer(slots, fill=0)
        next_sample = self.int_buffer(1, fill=0)
        radiance = self.output_buffer(budget)
        extend = self.kernel("pt_inplace_regen_extend")
        regenerate = self.kernel("pt_inplace_regen_regenerate")
        while True:
            program.launch(self.queue, regenerate, slots, camera, seed, np.int32(slots),
                           np.int32(sample_base), np.int32(budget), next_sample, *paths, alive, regenerated)
            if self.count_simd:
                self.simd.add_stream_step("generate", self.read_ints(regenerated, slots) > 0)
            live = self.read_ints(alive, slots)
            if not live.any():
                break   # budget spent and every path has ended
            program.launch(self.queue, extend, slots, *self.scene.args(), seed, np.int32(slots),
                           *paths, alive, radiance, lane_counts)
            if self.count_simd:
                self.count_stream_step(self.read_ints(lane_counts, slots, 4), capacity=slots)
        self.collect(film, radiance, budget)
