"""What both bidirectional path tracers share: BDPT's evaluator (the random walk and a connect
phase, bdpt_evaluator.py) whose connect phases hand their records to an image.

One pass: every sample of its budget goes through the evaluator; each connect phase's records
(pixel, value) go to an ImageSink, which adds them to the pass's image on the device
(toolkit/opencl/record_film.py: exact integer sums, so no float atomics and the same bits in any
order). The film adds the pass's image in float64: on the device where it has float64
(device_film.py DevicePassFilm, the host's bits; nothing is read until the film is asked for), else
on the host, which reads the image one pass behind. A
sample's light-tracing records land on other pixels than its own, so a pixel has no per-sample
values to square: a pass is an image, and the standard error comes from independent passes
(Film.add_pass).
Option `pool_size`: the samples in flight (default: the device's, toolkit/opencl/work_sizes.py: 4,096
on a CPU); each stores MAX_VERTICES eye and light vertices.
"""
import numpy as np

from toolkit.opencl.device_film import DevicePassFilm, has_fp64
from toolkit.opencl.record_film import RecordFilm, unit_exponent_for
from toolkit.techniques.base import pixel_count
from toolkit.techniques.bdpt_evaluator import REGENERATE_FRACTION, BdptEvaluator, BdptPoolTechnique
from toolkit.techniques.strategy_images import StrategyImages, strategy_count


class ImageSink:
    """Where a BDPT pass's connections go: their sum per pixel on the device (`film`, a
    RecordFilm), and with per-strategy images (`strategy_images`, a StrategyImages) each record
    to its strategy's image too (read back: a measurement, not the render's path)."""

    def __init__(self, film, strategy_images=None):
        self.film = film
        self.strategy_images = strategy_images

    def add(self, connections):
        weighted = connections.strategy is not None   # records of (unweighted value, MIS weight)
        if weighted:
            self.strategy_images.add(connections.values, connections.pixels, connections.strategy)
        self.film.add(connections.value_buffer, connections.pixel_buffer, connections.count, weighted)


class BdptTechnique(BdptPoolTechnique):
    family = "bdpt"

    def __init__(self, queue, device_scene, regenerate_fraction=REGENERATE_FRACTION, coalesced_scatter=True, pool_size=None,
                 strategy_max_edges=None, **kwargs):
        """`strategy_max_edges`: build the kernels that keep each connection strategy apart
        (toolkit.render(..., strategy_images=...)), with images for paths up to that many edges."""
        self.strategy_max_edges = strategy_max_edges
        self.strategy_images = None     # StrategyImages of the passes so far, when built for them
        self._record_film = None        # where the passes' records are summed (record_film)
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
        records = self.record_film(p.pixels)
        self.bdpt.evaluate(p, ImageSink(records, self.strategy_pass(camera, p.budget)))
        if self.film_on_device is None:
            self.film_on_device = has_fp64(self.queue.device)
        if self.film_on_device:              # the pass's image added to the film on the device: nothing read
            if film.device is None:
                film.keep_passes_on_device(DevicePassFilm(self.queue, p.pixels, self.local_size,
                                                          self.sources.toolkit_only(), owner=self.name))
            film.device.add(records.resolve_on_device(), spp)
            film.add_device_image_pass(spp)
            self.queue.flush()               # start the queued work now, not at the next wait
            return
        sums, done = records.resolve()       # no float64 on the device: the pass's image, read while the next pass runs
        shape = (int(camera["height"]), int(camera["width"]), 3)
        self.collect_later(done, lambda: film.add_pass(sums[:, :3].astype(np.float64).reshape(shape) / spp, spp,
                                                       nonfinite=int(sums[:, 3].sum())))

    def begin_render(self, camera, seed, spp):
        super().begin_render(camera, seed, spp)
        self._record_film = None    # a render stopped by an error may have left records in it

    def record_film(self, pixels):
        """The RecordFilm of an image of `pixels` pixels, made at its first pass."""
        if self._record_film is None or self._record_film.pixels != pixels:
            self._record_film = RecordFilm(self.queue, pixels, self.local_size, self.sources.toolkit_only(),
                                           unit_exponent=unit_exponent_for(self.scene.scene.emission_of.max()))
        return self._record_film

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
