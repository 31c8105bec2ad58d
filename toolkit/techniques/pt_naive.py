"""Plain path tracing (the talk's baseline): one path per work-item, camera to termination.

Kernel: cl/pt_naive.cl. A warp keeps issuing the extension loop until its longest path has
ended, so lanes whose paths ended early sit idle: with Russian roulette the SIMD efficiency
of the loop is low (the talk reports ~33% active threads per warp).
"""
import numpy as np
import pyopencl as cl

from .. import program
from .base import Technique


class PtNaive(Technique):
    name = "pt_naive"
    source = "pt_naive.cl"
    iterations = 0   # loop iterations over all passes so far (for per-iteration plots)

    def run_pass(self, film, camera, seed, sample_base, spp):
        pixels = camera["width"] * camera["height"]
        n = pixels * spp
        ctx = self.queue.context
        radiance = self.output_buffer(n)
        counts = cl.Buffer(ctx, cl.mem_flags.WRITE_ONLY, 16 * (program.padded(n) if self.count_simd else 1))
        kernel = self.kernel("pt_naive_render")
        program.launch(self.queue, kernel, n, *self.scene.args(), camera, seed,
                       np.int32(sample_base), np.int32(n), radiance, counts)
        self.collect(film, radiance, n)
        if self.count_simd:
            lanes = np.empty((n, 4), np.int32)
            cl.enqueue_copy(self.queue, lanes, counts)
            # Every lane generates its camera ray once; then the loop runs as long as the warp's longest path.
            self.simd.add_stream_step("generate", np.ones(n, bool))
            self.simd.add_warp_loops("extend", lanes[:, 0])
            self.simd.add_loop_iterations("extend", lanes[:, 0], first_iteration=self.iterations)
            self.iterations += int(lanes[:, 0].max())
            # A shadow ray is cast once per vertex at most; the warp issues the shadow step in each of its iterations.
            self.simd.add_warp_loops("shadow", lanes[:, 0], active=lanes[:, 3].sum())
            self.traversal.add_warp_loops("closest", lanes[:, 1])
            self.traversal.add_warp_loops("shadow", lanes[:, 2])
