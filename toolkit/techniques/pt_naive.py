"""Plain path tracing (the talk's baseline): one path per work-item, camera to termination.

Kernel: cl/pt_naive.cl. A warp keeps issuing the extension loop until its longest path has
ended, so lanes whose paths ended early sit idle: with Russian roulette the SIMD efficiency
of the loop is low (the talk reports ~33% active threads per warp).
"""
import numpy as np

from toolkit.techniques.base import Technique


class PtNaive(Technique):
    name = "pt_naive"
    family = "pt"
    source = "pt_naive.cl"
    iterations = 0   # loop iterations over all passes so far (for per-iteration plots)

    def run_pass(self, film, camera, seed, sample_base, spp):
        n = int(camera["width"] * camera["height"]) * spp
        radiance = self.output_buffer(n)
        lane_counts = self.lane_counts_buffer(n if self.count_simd else 1)
        self.launch(self.kernel("pt_naive_render"), n, *self.scene.args(), camera, seed,
                    np.int32(sample_base), np.int32(n), radiance, lane_counts)
        self.collect(film, radiance, n)
        self.count_render(lane_counts, n)

    def count_render(self, lane_counts, n):
        """SIMD counters of one launch (a no-op unless count_simd)."""
        if not self.count_simd:
            return
        lanes = self.read_lane_counts(lane_counts, n)
        iterations = lanes["work"]
        # Every lane generates its camera ray once; then the loop runs as long as the warp's longest path.
        self.simd.add_stream_step("generate", np.ones(n, bool))
        self.simd.add_warp_loops("extend", iterations)
        self.simd.add_loop_iterations("extend", iterations, first_iteration=self.iterations)
        self.iterations += int(iterations.max())
        # A shadow ray is cast once per vertex at most; the warp issues the shadow step in each of its iterations.
        self.simd.add_warp_loops("shadow", iterations, active=lanes["shadow_rays"].sum())
        self.traversal.add_warp_loops("closest", lanes["closest_steps"])
        self.traversal.add_warp_loops("shadow", lanes["shadow_steps"])
