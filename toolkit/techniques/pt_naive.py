"""Plain path tracing (the talk's baseline): one path per work-item, camera to termination.

Kernel: cl/pt_naive.cl. A warp keeps issuing the extension loop until its longest path has
ended, so lanes whose paths ended early sit idle: with Russian roulette the SIMD efficiency
of the loop is low (the talk reports ~33% active threads per warp).
"""
from dataclasses import dataclass

import pyopencl as cl

from toolkit.core.layout import HARD_MAX_BOUNCES, PT_PASS
from toolkit.techniques.base import Technique, pixel_count


@dataclass
class NaiveBuffers:
    """What one pass of pt_naive writes on the device."""
    radiance: cl.Buffer      # float4 per sample: its value (DeviceMemory.output_buffer; .w = -1 until written)
    lane_counts: cl.Buffer   # LaneCounts per sample: its loop iterations and BVH steps (one, unused, without COUNT_SIMD)


class PtNaive(Technique):
    name = "pt_naive"
    family = "pt"
    source = "pt_naive.cl"

    def run_pass(self, film, camera, seed, sample_base, spp):
        n = pixel_count(camera) * spp   # one work-item per sample
        mem = NaiveBuffers(radiance=self.memory.output_buffer(n),
                           lane_counts=self.memory.lane_counts_buffer(n if self.count_simd else 1))
        pass_args = PT_PASS.record(seed=seed, sample_base=sample_base, budget=n, capacity=0)
        self.kernels.launch("pt_naive_render", n, **self.kernels.scene_args(), cam=camera, pass_args=pass_args,
                            radiance=mem.radiance, lane_counts=mem.lane_counts)
        self.collect(film, mem.radiance, n)
        self.count_render(mem.lane_counts, n)

    def count_render(self, lane_counts, n):
        """SIMD counters of one launch (a no-op unless count_simd), summed on the device."""
        if not self.count_simd:
            return
        def replay(recorder, sums):
            # Every lane generates its camera ray once; then the loop runs as long as the warp's longest path.
            recorder.simd_counter().add_stream_step("generate", n)
            recorder.warp_loops(recorder.simd_counter(), "extend", sums, "work")
            recorder.loop_iterations("extend", sums, numbered=True)
            # A shadow ray is cast once per vertex at most; the warp issues the shadow step in each of its iterations.
            recorder.warp_loops(recorder.simd_counter(), "shadow", sums, "work", active="shadow_rays")
            recorder.warp_loops(recorder.traversal_counter(), "closest", sums, "closest_steps")
            recorder.warp_loops(recorder.traversal_counter(), "shadow", sums, "shadow_steps")
        self.recorder.lanes(replay, lane_counts, 4, n, bins=HARD_MAX_BOUNCES + 2)
