"""What both bidirectional path tracers share: BDPT's evaluator (the random walk and a connect
phase, bdpt_evaluator.py) whose connect phases hand their records to an image.

One pass: every sample of its budget goes through the evaluator; each connect phase's records
(pixel, value) go to an ImageSink, which adds them up per pixel in float64 (no float atomics
on the device). So a pass is an image, and the standard error comes from independent passes.
Option `pool_size`: the samples in flight (default: the device's, toolkit/opencl/work_sizes.py: 4,096
on a CPU); each stores MAX_VERTICES eye and light vertices.
"""
import numpy as np

from toolkit.techniques.base import pixel_count
from toolkit.techniques.bdpt_evaluator import BdptEvaluator, BdptPoolTechnique, per_pixel_sums
from toolkit.techniques.strategy_images import StrategyImages, strategy_count


class ImageSink:
    """Where a BDPT pass's connections go: their sum per pixel (float64), and with per-strategy
    images (`strategy_images`, a StrategyImages) each record to its strategy's image too."""

    def __init__(self, pixels, strategy_images=None):
        self.image = np.zeros((pixels, 3))   # (pixels, 3) float64 sum of the connections
        self.strategy_images = strategy_images
        self.nonfinite = 0                   # records dropped for a NaN or infinite value

    def add(self, connections):
        values, pixels = connections.values, connections.pixels
        if connections.strategy is not None:   # records of (unweighted value, MIS weight)
            self.strategy_images.add(values, pixels, connections.strategy)
            values = weighted(values, pixels)
        self.image += self.per_pixel(values, pixels)

    def per_pixel(self, values, pixels):
        """Records (value, pixel) added per pixel in float64; non-finite ones are counted and dropped."""
        ok = pixels >= 0
        v, p = values[ok, :3], pixels[ok]
        sums = per_pixel_sums(v, p, len(self.image))
        if np.isfinite(sums).all():      # a non-finite record would show in its pixel's sum
            return sums
        finite = np.isfinite(v).all(1)
        self.nonfinite += int((~finite).sum())
        return per_pixel_sums(v[finite], p[finite], len(self.image))


def weighted(values, pixels):
    """Records of the STRATEGY_IMAGES kernels, (unweighted value, MIS weight), weighted as the
    normal kernels write them (in float32)."""
    out = values.copy()
    used = pixels >= 0      # the others are unwritten memory
    out[used, :3] *= values[used, 3:]
    return out


class BdptTechnique(BdptPoolTechnique):
    family = "bdpt"

    def __init__(self, queue, device_scene, regenerate_fraction=0.6, coalesced_scatter=True, pool_size=None,
                 strategy_max_edges=None, **kwargs):
        """`strategy_max_edges`: build the kernels that keep each connection strategy apart
        (toolkit.render(..., strategy_images=...)), with images for paths up to that many edges."""
        self.strategy_max_edges = strategy_max_edges
        self.strategy_images = None     # StrategyImages of the passes so far, when built for them
        defines = {}
        if strategy_max_edges:
            defines.update(STRATEGY_IMAGES=True, STRATEGY_MAX_EDGES=strategy_max_edges,
                           STRATEGY_COUNT=strategy_count(strategy_max_edges))
        super().__init__(queue, device_scene, defines, pool_size, coalesced_scatter, **kwargs)
        self.bdpt = BdptEvaluator(self.bdpt_context, self.connect_phase(), self.pool_size, regenerate_fraction,
                                  self.max_vertices)

    def connect_phase(self):
        """The technique's connect phase: (PassState, terminated count) -> Connections."""
        raise NotImplementedError

    def run_pass(self, film, camera, seed, sample_base, spp):
        p = self.bdpt.start_pass(camera, seed, sample_base, pixel_count(camera) * spp)
        image = ImageSink(p.pixels, self.strategy_pass(camera, p.budget))
        self.bdpt.evaluate(p, image)
        film.add_pass(image.image.reshape(int(camera["height"]), int(camera["width"]), 3) / spp, spp,
                      nonfinite=image.nonfinite)

    def strategy_pass(self, camera, budget):
        """Per-strategy images (None unless built for them): the pass's samples count towards them."""
        if not self.strategy_max_edges:
            return None
        width, height = int(camera["width"]), int(camera["height"])
        if self.strategy_images is None:
            self.strategy_images = StrategyImages(self.strategy_max_edges, width, height)
        self.strategy_images.spp += budget // pixel_count(camera)
        return self.strategy_images

    # --- measuring and inspecting ------------------------------------------------------------

    def read_vertices(self):
        """The vertex memory of the last samples of the last pass (BdptEvaluator.read_vertices)."""
        return self.bdpt.read_vertices()

    def eye_paths_to_lights(self, most):
        """Up to `most` real paths of the last pass: eye subpaths that end on the front of a
        light, in light -> eye order (path[-1] is the camera). The MIS tests and the grader's
        MIS checks split them into every (s, t)."""
        eye, eye_count, _, _ = self.read_vertices()
        paths = []
        for slot in range(len(eye_count)):
            for k in range(1, eye_count[slot]):
                v = eye[slot, k]
                if v["light"] >= 0 and np.dot(v["normal"][:3], v["wo"][:3]) > 0:
                    paths.append(eye[slot, :k + 1][::-1].copy())
                    break
            if len(paths) >= most:
                break
        return paths
