"""One technique rendering a little at a time into one image, so the image converges while you
watch: `advance()` runs one short pass and returns.

A plain `toolkit.render` runs its whole sample budget before it returns. The live view needs the
image between passes, and controls (pause, a new technique) that act within a pass, so here the
render loop of Technique.render is run one pass per call, with the plain render's passes (about
2^18 samples: a quarter to half a second on the 2-core CPU). Metropolis (mlt) is no pass-based
technique: its chains keep running, and each call runs iterations of every chain for about
pass_seconds.
"""
import time

import numpy as np

from toolkit.core.film import Film
from toolkit.core.layout import MltMode
from toolkit.techniques import get_technique
from toolkit.techniques.base import pixel_count
from toolkit.demo.lanes_picture import WarpSampler

# Seconds a pass should about take: a pass of over four times this is halved, so that a pause or a
# change still acts within about a second; the per-pass work (the film, the counters, the page's
# update) stays a small share of it.
PASS_SECONDS = 0.25


class ProgressiveRender:
    """A technique built once for a scene and a size, adding a pass to its film per advance()."""

    def __init__(self, queue, device_scene, technique, width, height, seed=0, pass_seconds=PASS_SECONDS):
        cls, options = get_technique(technique)
        self.name = technique
        self.tech = cls(queue, device_scene, count_simd=True, **options)
        # The same counters, and beside them the lanes of the first few warps of every step.
        # Metropolis draws its drains' steps: each of its iterations is one (lanes_picture.py).
        self.tech.recorder.simd = WarpSampler(self.tech.warp_width, drains=self.tech.family == "mlt")
        self.width, self.height = width, height
        self.seed = np.uint32(seed)
        self.camera = device_scene.camera(width, height)
        self.pass_seconds = pass_seconds
        self.film = Film(width, height)
        self.seconds = 0.0          # time spent rendering (this technique's passes only)
        self.spp = 0                # samples per pixel so far
        # The passes of a plain render (Technique.spp_per_pass: about 2^18 samples, several streams' worth for the
        # stream techniques, so their steady state shows and their drains cost as little as there); halved
        # only where one takes far longer than pass_seconds (a slow device, a large image).
        self.pass_spp = self.tech.spp_per_pass(width * height, 1 << 30)

    def advance(self):
        """Render one pass (pass_spp samples per pixel, same seeds as a plain render would use)."""
        count = self.pass_spp
        start = time.perf_counter()
        self.tech.run_pass(self.film, self.camera, self.seed, self.spp, count)
        self.tech.finish_collect()
        took = time.perf_counter() - start
        self.seconds += took
        self.spp += count
        if took > 4 * self.pass_seconds and self.pass_spp > 1:
            self.pass_spp //= 2      # a control should act within about a second

    def image(self):
        return self.film.image()

    @property
    def samples(self):
        return self.film.samples

    def efficiency(self):
        """SIMD efficiency per phase so far (toolkit/core/simd.py): active lanes / lanes issued."""
        return self.tech.recorder.simd.efficiency()


class ProgressiveMetropolis(ProgressiveRender):
    """mlt: its chains start once (the technique's `start`; by default from the pool of all chains'
    candidates) and then mutate for as long as the view runs; each advance() runs iterations for
    about pass_seconds."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.chains = None

    def advance(self):
        tech, start = self.tech, time.perf_counter()
        if self.chains is None:
            self.chains = tech.begin(self.camera, self.seed, tech.chain_count)
        while True:
            tech.iterate(self.chains, self.chains.count, MltMode.MUTATE)
            if time.perf_counter() - start >= self.pass_seconds:
                break
        self.seconds += time.perf_counter() - start
        self.spp = self.chains.mutations / pixel_count(self.camera)   # mutations per pixel

    def image(self):
        if self.chains is None:
            return np.zeros((self.height, self.width, 3))
        return self.tech.image(self.chains).reshape(self.height, self.width, 3)

    @property
    def samples(self):
        return 0 if self.chains is None else self.chains.mutations


def progressive(queue, device_scene, technique, width, height, seed=0, pass_seconds=PASS_SECONDS):
    """The progressive form of `technique`: Metropolis's chains, or passes into a film."""
    kind = ProgressiveMetropolis if get_technique(technique)[0].family == "mlt" else ProgressiveRender
    return kind(queue, device_scene, technique, width, height, seed, pass_seconds)
