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

from toolkit.techniques.strategy_images import DEFAULT_MAX_EDGES


def render_strategies(scene=None, technique="bdpt_parallel_connect", spp=16, seed=0, resolution=None,
                      device=None, max_edges=DEFAULT_MAX_EDGES, bvh="wide", progress=False):
    """Render with the strategy-image kernels; returns (the BDPT image, StrategyImages)."""
    from toolkit.api import as_scene
    from toolkit.opencl.device import get_queue
    from toolkit.opencl.device_scene import DeviceScene
    from toolkit.techniques import get_technique
    from toolkit.core.validate import InputError, render_args
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
    from toolkit.core.images import write_image
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
