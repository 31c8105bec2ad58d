"""What every technique shares: the build of its kernel for a scene, and the render loop
that splits the sample budget into passes and feeds the film."""
import time

import numpy as np

from .. import program
from ..film import Film
from ..simd import PhaseCounter


class Technique:
    """Base class. A technique sets `name`, `source` (its cl/ file) and implements `run_pass`."""
    name = None
    source = None
    # Work-items per launch we aim for: enough to fill a GPU, small enough to read back often.
    target_batch = 1 << 18

    def __init__(self, queue, device_scene, warp_width=32, count_simd=True, extra_defines=None):
        self.queue = queue
        self.scene = device_scene
        self.warp_width = warp_width
        self.count_simd = count_simd
        defines = dict(device_scene.scene.features())
        defines["COUNT_SIMD"] = bool(count_simd)
        defines["WARP_WIDTH"] = warp_width
        defines.update(extra_defines or {})
        self.defines = defines
        start = time.perf_counter()
        self.program = program.build(queue.context, self.source, defines)
        self.build_seconds = time.perf_counter() - start
        self.simd = PhaseCounter(warp_width)
        self.traversal = PhaseCounter(warp_width)

    def kernel(self, name):
        """The kernel object, retrieved once (each retrieval makes a new cl.Kernel)."""
        return program.kernel(self.program, name)

    def render(self, width, height, spp, seed=0, progress=None):
        """Render `spp` samples per pixel; returns the film (see toolkit.api.render)."""
        film = Film(width, height)
        camera = self.scene.camera(width, height)
        per_pass = max(1, min(spp, self.target_batch // (width * height)))
        start = 0
        while start < spp:
            count = min(per_pass, spp - start)
            self.run_pass(film, camera, np.uint32(seed), start, count)
            start += count
            if progress is not None:
                progress.update(count)
        self.queue.finish()
        return film

    def run_pass(self, film, camera, seed, sample_base, spp):
        raise NotImplementedError

    def simd_efficiency(self):
        return self.simd.efficiency() if self.count_simd else {}
