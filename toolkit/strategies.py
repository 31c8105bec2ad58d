"""Where BDPT's image comes from: one image per connection strategy (s, t), with and without
its MIS weight (Veach's thesis, figure 10.3; pbrt-v4's `visualizestrategies`), and each
strategy's share of the variance. `python -m toolkit render --technique bdpt_* --strategies DIR`.

A strategy (s, t) joins s light vertices and t eye vertices into a path of k = s + t - 1 edges.
Every path of k edges can be made by k + 1 strategies (s = 0 .. k); MIS weighs each so that the
weights of one path add up to one, so the weighted strategy images add up to the BDPT image
(tests/test_strategies_images.py), and each unweighted image is a whole estimate of the light
carried by paths of k edges, good where that strategy samples well and noisy elsewhere.

Strategies of paths up to `max_edges` edges get their own images; longer paths are summed in
one more weighted image, so that nothing is left out of the sum. The kernels keep strategies
apart only when built with STRATEGY_IMAGES (cl/bdpt.h): the normal kernels do not change.

Variance share: a strategy's image, as an estimate of its part of the BDPT image, has a variance
per pixel; the share is its sum over pixels (of the luminance) over the sum for all listed
strategies. Covariances between the strategies of one sample (which share vertices) are left out.
"""
import json
from pathlib import Path

import numpy as np

from .layout import LUMINANCE_WEIGHTS

DEFAULT_MAX_EDGES = 5


def strategy_count(max_edges):
    """Strategies of paths with 1 .. max_edges edges (k + 1 each)."""
    return max_edges * (max_edges + 3) // 2


def strategy_index(s, t, max_edges):
    """The index of strategy (s, t) (numpy arrays or ints): ordered by path edges k = s + t - 1,
    then by s; strategy_count(max_edges) for longer paths. cl/bdpt.h's strategy_index is the same."""
    k = np.asarray(s) + np.asarray(t) - 1
    return np.where(k <= max_edges, (k - 1) * (k + 2) // 2 + s, strategy_count(max_edges))


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
        ok = np.isfinite(values).all(1) & np.isfinite(weighted).all(1)    # as reduce_records drops them
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


def render_strategies(scene=None, technique="bdpt_parallel_connect", spp=16, seed=0, resolution=None,
                      device=None, max_edges=DEFAULT_MAX_EDGES, bvh="wide", progress=False):
    """Render with the strategy-image kernels; returns (the BDPT image, StrategyImages)."""
    from .api import as_scene
    from .device import get_queue
    from .device_scene import DeviceScene
    from .techniques import get_technique
    from .validate import InputError, render_args
    cls, options = get_technique(technique)
    if cls.family != "bdpt":
        raise InputError(f"--strategies needs a bidirectional technique (bdpt_naive_connect or "
                         f"bdpt_parallel_connect), not {technique}")
    if isinstance(max_edges, bool) or not isinstance(max_edges, int) or not 1 <= max_edges <= 10:
        raise InputError(f"max_edges must be a whole number 1 .. 10, got {max_edges!r}")
    scene = as_scene(scene)
    width, height = resolution or (scene.camera.width, scene.camera.height)
    spp, seed, width, height = render_args(spp, seed, width, height, None)
    queue = get_queue(device)
    tech = cls(queue, DeviceScene(queue, scene, bvh=bvh), count_simd=False, strategy_max_edges=max_edges,
               **options)
    bar = None
    if progress:
        import sys
        from tqdm.auto import tqdm
        bar = tqdm(total=spp, unit="spp", desc=f"{technique} strategies", file=sys.stderr, leave=False)
    film = tech.render(width, height, spp, seed=seed, progress=bar)
    if bar is not None:
        bar.close()
    return film.image(), tech.strategy_images


def write_strategies(folder, image, result, scene_name, technique):
    """s<S>_t<T>_weighted.exr / _unweighted.exr per strategy, longer_weighted.exr, full.exr and
    strategies.json (each strategy's share of the variance and of the image). Returns the report."""
    from .images import write_image
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    images, longer = result.images()
    variance = result.variance()
    total_var = sum(variance.values())
    full_sum = float(image.sum())
    rows = []
    for (s, t), (weighted, unweighted) in images.items():
        write_image(folder / f"s{s}_t{t}_weighted.exr", weighted.astype(np.float32))
        write_image(folder / f"s{s}_t{t}_unweighted.exr", unweighted.astype(np.float32))
        rows.append({"s": s, "t": t, "edges": s + t - 1,
                     "image_share": float(weighted.sum()) / full_sum if full_sum > 0 else 0.0,
                     "variance_share": variance[(s, t)] / total_var if total_var > 0 else 0.0,
                     "variance": variance[(s, t)]})
    write_image(folder / "longer_weighted.exr", longer.astype(np.float32))
    write_image(folder / "full.exr", image.astype(np.float32))
    report = {"scene": scene_name, "technique": technique, "max_edges": result.max_edges, "spp": result.spp,
              "resolution": [result.width, result.height],
              "longer_paths_image_share": float(longer.sum()) / full_sum if full_sum > 0 else 0.0,
              "strategies": rows}
    (folder / "strategies.json").write_text(json.dumps(report, indent=1))
    return report


def format_strategies(report):
    lines = [f"{report['technique']} on {report['scene']}, {report['spp']} spp: per strategy (s light, "
             f"t eye vertices), paths up to {report['max_edges']} edges",
             f"  {'s':>2s} {'t':>2s} {'edges':>5s} {'share of image':>15s} {'share of variance':>18s}"]
    for r in report["strategies"]:
        lines.append(f"  {r['s']:2d} {r['t']:2d} {r['edges']:5d} {r['image_share']:15.1%} {r['variance_share']:18.1%}")
    lines.append(f"  longer paths: {report['longer_paths_image_share']:.1%} of the image")
    lines.append("  variance share: of the summed per-strategy variances (covariances left out)")
    return "\n".join(lines)
