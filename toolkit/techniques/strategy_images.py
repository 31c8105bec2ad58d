"""The per-strategy accumulator of BDPT's connect phase: which (s, t) a connection belongs to
(strategy_index, toolkit/core/bdpt_indices.py) and the per-strategy sums the kernels built with STRATEGY_IMAGES add into.
toolkit/measure/strategies.py turns them into images and a report; its docstring explains the
strategies."""
import numpy as np

from toolkit.core.layout import LUMINANCE_WEIGHTS
# The numbering, shared with the kernels (generated into layout.h): by path edges k = s + t - 1, then by s.
from toolkit.core.bdpt_indices import strategy_count, strategy_index

DEFAULT_MAX_EDGES = 5   # `render --strategies`: paths of up to 5 edges get images of their own


def strategies(max_edges):
    """[(s, t)] in index order."""
    return [(s, k + 1 - s) for k in range(1, max_edges + 1) for s in range(k + 1)]


class StrategyImages:
    """Per-strategy sums of a render's connections, per pixel in float64 (as the BDPT image)."""

    def __init__(self, max_edges, width, height):
        self.max_edges, self.width, self.height = max_edges, width, height
        n, npix = strategy_count(max_edges) + 1, width * height
        self.weighted = np.zeros((n, npix, 3))       # the last row: all longer paths
        self.unweighted = np.zeros((n, npix, 3))
        self.luminance_sq = np.zeros((n, npix))    # sum of squared (weighted) luminance, per record
        self.spp = 0

    def add(self, values, pixels, index):
        """Connection records: values (n, 4) float32 = (unweighted value, MIS weight), pixels (n,)
        (-1: none), index (n,) the strategy of each (strategy_index)."""
        used = pixels >= 0      # the others are unwritten memory
        values, pixels, index = values[used], pixels[used], index[used]
        weighted = values[:, :3] * values[:, 3:]                          # float32, as on the device
        ok = np.isfinite(values).all(1) & np.isfinite(weighted).all(1)    # as the image drops them (cl/record_film.cl)
        values, weighted, pixels, index = values[ok], weighted[ok].astype(np.float64), pixels[ok], index[ok]
        unweighted = values[:, :3].astype(np.float64)
        shape = self.luminance_sq.shape                 # (strategies, pixels)
        at = index * shape[1] + pixels                  # one bin per (strategy, pixel)

        def per_bin(values):
            return np.bincount(at, values, shape[0] * shape[1]).reshape(shape)
        for c in range(3):
            self.weighted[:, :, c] += per_bin(weighted[:, c])
            self.unweighted[:, :, c] += per_bin(unweighted[:, c])
        self.luminance_sq += per_bin((weighted @ np.array(LUMINANCE_WEIGHTS)) ** 2)

    def images(self):
        """{(s, t): (weighted, unweighted)} as (H, W, 3) images, and the weighted image of longer paths."""
        shape = (self.height, self.width, 3)
        out = {st: (self.weighted[i].reshape(shape) / self.spp, self.unweighted[i].reshape(shape) / self.spp)
               for i, st in enumerate(strategies(self.max_edges))}
        return out, self.weighted[-1].reshape(shape) / self.spp

    def variance(self):
        """{(s, t): the variance of its weighted image, summed over pixels (luminance)}.
        A pixel's estimate is (1/spp) sum over samples of Y, a sample's contribution there: its own
        spp samples for t >= 2; for t = 1 (light tracing) all width x height x spp samples, whose
        light subpaths are independent of their pixel. So Var = (sum Y^2 - (sum Y)^2 / n) / spp^2."""
        luminance = self.weighted @ np.array(LUMINANCE_WEIGHTS)
        out = {}
        for i, (s, t) in enumerate(strategies(self.max_edges)):
            n = self.spp * (self.width * self.height if t == 1 else 1)
            per_pixel = (self.luminance_sq[i] - luminance[i] ** 2 / n) / self.spp ** 2
            out[(s, t)] = float(np.maximum(per_pixel, 0.0).sum())
        return out
