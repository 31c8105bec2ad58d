"""Startup bias of many parallel Metropolis chains, measured (the talk's slide "Startup Bias").

Each chain of `mlt` starts somewhere that is not distributed like f (start = naive: one large
step, a BDPT sample) and needs mutations to forget it; with many chains and few mutations per
chain the image is biased. Over R independent runs (seeds) of the same settings, the error of
pixel j against the reference, e_j = I_j - R_j, splits into

    variance_j = the spread of e_j over the runs (sample variance, ddof = 1)
    bias_j^2   = mean(e_j)^2 - variance_j / R - ref_stderr_j^2

(the last two terms remove, in expectation, the noise of the mean over runs and of the
reference itself, so bias^2 is unbiased and may come out slightly negative when it is ~0).
Both are averaged over the pixels and divided by the mean squared reference value, so they
are relative squared errors: relative RMSE^2 of one run = bias^2 + variance (+ the reference's).
"""
import sys
import time

import numpy as np

from toolkit.api import as_scene, render
from toolkit.measure.reference import reference_at


def measure(scene, chains, mutations_per_chain, start="naive", runs=8, resolution=(16, 16), seed=0,
            options=None, device=None):
    """bias^2, variance (relative, as above) and the seconds of one run, for `chains` chains
    making `mutations_per_chain` mutations each (chains x mutations_per_chain must be a
    multiple of the pixels: spp = mutations / pixels)."""
    scene = as_scene(scene)
    width, height = resolution
    pixels = width * height
    total = chains * mutations_per_chain
    if total % pixels:
        raise ValueError(f"{chains} chains x {mutations_per_chain} mutations is not a multiple of {pixels} pixels")
    ref, ref_err = reference_at(scene, width, height)
    images, seconds = [], []
    for r in range(runs):
        start_time = time.perf_counter()
        result = render(scene, technique="mlt", spp=total // pixels, seed=seed + r, resolution=resolution,
                        count_simd=False, device=device,
                        options={"chains": chains, "start": start, **(options or {})})
        seconds.append(time.perf_counter() - start_time)
        images.append(result.image)
    return split_error(np.array(images), ref, ref_err) | {
        "chains": chains, "mutations_per_chain": mutations_per_chain, "start": start, "runs": runs,
        "seconds": float(np.median(seconds)), "images": np.array(images)}


def split_error(images, ref, ref_err):
    """{"bias2", "variance", "mean_image"} of R images (R, H, W, 3) against the reference."""
    runs = len(images)
    err = images - ref
    mean = err.mean(0)
    var = err.var(0, ddof=1)
    scale = np.mean(ref ** 2)
    bias2 = mean ** 2 - var / runs - ref_err ** 2
    return {"bias2": float(bias2.mean() / scale), "variance": float(var.mean() / scale),
            "mean_image": images.mean(0)}


def sweep(scene, chain_counts=(256, 1024, 4096), mutations=(1, 4, 16), starts=("naive", "resample"), runs=8,
          resolution=(16, 16), seed=0, progress=print):
    """measure() over a grid; rows without the images, for tables and plots."""
    rows = []
    for start in starts:
        for c in chain_counts:
            for m in mutations:
                row = measure(scene, c, m, start=start, runs=runs, resolution=resolution, seed=seed)
                row = {k: v for k, v in row.items() if k not in ("images", "mean_image")}
                rows.append(row)
                if progress:
                    progress(format_row(row))
    return rows


def format_row(row):
    return (f"start {row['start']:<9} chains {row['chains']:>6}  mutations/chain {row['mutations_per_chain']:>5}  "
            f"bias^2 {row['bias2']:.2e}  variance {row['variance']:.2e}  {row['seconds']:.2f} s/run")


if __name__ == "__main__":
    sweep(sys.argv[1] if len(sys.argv) > 1 else "scenes/covered_lamp")
