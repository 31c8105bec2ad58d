"""Where BDPT's image comes from: one image per connection strategy (s, t), with and without
its MIS weight (Veach's thesis, figure 10.3; pbrt-v4's `visualizestrategies`), and each
strategy's share of the variance. `toolkit.render(..., technique="bdpt_*", strategy_images=K)` keeps
them (result.strategy_images, a StrategyImages); this module writes them and a report:
`python -m toolkit render --technique bdpt_* --strategies DIR`.

A strategy (s, t) joins s light vertices and t eye vertices into a path of k = s + t - 1 edges.
Every path of k edges can be made by k + 1 strategies (s = 0 .. k); MIS weighs each so that the
weights of one path add up to one, so the weighted strategy images add up to the BDPT image
(tests/test_strategy_images.py), and each unweighted image is a whole estimate of the light
carried by paths of k edges, good where that strategy samples well and noisy elsewhere.

Strategies of paths up to `max_edges` edges get their own images; longer paths are summed in
one more weighted image, so that nothing is left out of the sum. The kernels keep strategies
apart only when built with STRATEGY_IMAGES (cl/bdpt.h): the normal kernels do not change.

The folder: a second run into the same folder must not leave images of the first that its
strategies.json no longer lists (a smaller K writes fewer). So the folder must be new, empty, or
hold only what an earlier run wrote (the names below and strategies.json), checked before the
render: a folder of other files is refused rather than mixed with, or cleared of, files that are
not ours. After writing, the images of an earlier run that this one did not write are removed.

Variance share: a strategy's image, as an estimate of its part of the BDPT image, has a variance
per pixel; the share is its sum over pixels (of the luminance) over the sum for all listed
strategies. Covariances between the strategies of one sample (which share vertices) are left out.
"""
import json
import os
import re
from pathlib import Path

import numpy as np

from toolkit.core.images import write_atomically, write_image
from toolkit.core.validate import InputError, writable_folder

# Every name write_strategies writes (the module docstring: only these may be in the folder).
OUR_FILE = re.compile(r"(s\d+_t\d+_(un)?weighted|longer_weighted|full)\.(exr|png)|strategies\.json")


def check_strategies_folder(folder):
    """Before the render: `folder` can be written, and is new, empty or an earlier output of
    write_strategies; else an InputError that names what else it holds."""
    folder = writable_folder(folder, "--strategies")
    others = sorted(name for name in os.listdir(folder) if not OUR_FILE.fullmatch(name))
    if others:
        raise InputError(f"--strategies {folder}: holds {', '.join(others[:3])}{' ...' if len(others) > 3 else ''}, "
                         "which --strategies did not write; give a new or empty folder (the images of an earlier "
                         "--strategies run there are replaced)")
    return folder


def write_strategies(folder, image, result, scene_name, technique):
    """s<S>_t<T>_weighted.exr / _unweighted.exr per strategy, longer_weighted.exr, full.exr and
    strategies.json (each strategy's share of the variance and of the image). Returns the report."""
    folder = check_strategies_folder(folder)
    images, longer = result.images()
    variance = result.variance()
    total_var = sum(variance.values())
    full_sum = float(image.sum())
    rows, written = [], []
    for (s, t), (weighted, unweighted) in images.items():
        written += write_image(folder / f"s{s}_t{t}_weighted.exr", weighted.astype(np.float32))
        written += write_image(folder / f"s{s}_t{t}_unweighted.exr", unweighted.astype(np.float32))
        rows.append({"s": s, "t": t, "edges": s + t - 1,
                     "image_share": float(weighted.sum()) / full_sum if full_sum > 0 else 0.0,
                     "variance_share": variance[(s, t)] / total_var if total_var > 0 else 0.0,
                     "variance": variance[(s, t)]})
    written += write_image(folder / "longer_weighted.exr", longer.astype(np.float32))
    written += write_image(folder / "full.exr", image.astype(np.float32))
    report = {"scene": scene_name, "technique": technique, "max_edges": result.max_edges, "spp": result.spp,
              "resolution": [result.width, result.height],
              "longer_paths_image_share": float(longer.sum()) / full_sum if full_sum > 0 else 0.0,
              "strategies": rows, "files": sorted(path.name for path in written)}
    write_atomically(folder / "strategies.json",
                     lambda tmp: Path(tmp).write_text(json.dumps(report, indent=1), encoding="utf-8"))
    _remove_earlier(folder, set(report["files"]) | {"strategies.json"})
    return report


def _remove_earlier(folder, kept):
    """Remove the images of an earlier run in `folder` that this run did not write."""
    for name in os.listdir(folder):
        if OUR_FILE.fullmatch(name) and name not in kept and (folder / name).is_file():
            (folder / name).unlink()


def format_strategies(report):
    lines = [f"{report['technique']} on {report['scene']}, {report['spp']} spp: per strategy (s light, "
             f"t eye vertices), paths up to {report['max_edges']} edges",
             f"  {'s':>2s} {'t':>2s} {'edges':>5s} {'share of image':>15s} {'share of variance':>18s}"]
    for r in report["strategies"]:
        lines.append(f"  {r['s']:2d} {r['t']:2d} {r['edges']:5d} {r['image_share']:15.1%} {r['variance_share']:18.1%}")
    lines.append(f"  longer paths: {report['longer_paths_image_share']:.1%} of the image")
    lines.append("  variance share: of the summed per-strategy variances (covariances left out)")
    return "\n".join(lines)
