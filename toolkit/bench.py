"""`python -m toolkit bench`: samples/s of each technique and the ratios between them, measured
in one run with interleaved repetitions (technique A, B, C, A, B, C, ...) and their medians,
so a slow moment of the machine does not favour one technique. SIMD counters are off here.
"""
import statistics

import numpy as np

from .api import as_scene, render
from .device import has_gpu
from .techniques import get_technique


DEFAULT = ("pt_naive", "pt_inplace_regen", "pt_compact_regen", "pt_compact_regen/multipass",
           "bdpt_naive_connect", "bdpt_parallel_connect", "bdpt_parallel_connect/direct_scatter")


def bench(scene=None, techniques=DEFAULT, spp=16, resolution=(128, 128), repeats=3, seed=0, device=None,
          bvh="wide", general=False):
    scene = as_scene(scene)
    for name in techniques:   # warm-up: kernel builds and BVH outside the timings
        render(scene, technique=name, spp=1, resolution=(16, 16), device=device, count_simd=False, bvh=bvh,
               general=general)
    rates = {name: [] for name in techniques}
    device_name = None
    for r in range(repeats):
        for name in techniques:
            # Bidirectional samples (and Metropolis mutations, each one) cost ~10x more: an eighth of
            # the budget keeps the runs comparable in length.
            n = max(1, spp // 8) if family(name) in ("bdpt", "mlt") else spp
            result = render(scene, technique=name, spp=n, seed=seed + r, resolution=resolution,
                            device=device, count_simd=False, bvh=bvh, general=general)
            rates[name].append(result.stats["samples_per_second"])
            device_name = result.stats["device"]
    median = {name: statistics.median(v) for name, v in rates.items()}
    base = techniques[0]
    return {"scene": scene.name, "device": device_name, "gpu": has_gpu(), "spp": spp, "bvh": bvh, "general": general,
            "resolution": list(resolution), "repeats": repeats,
            "techniques": {name: {"samples_per_second": median[name], "runs": rates[name],
                                  f"ratio_to_{base}": median[name] / median[base]} for name in techniques}}


def equal_time(scene, techniques, seconds, resolution=(32, 32), seed=0, device=None, bvh="wide", repeats=1):
    """Each technique renders for about `seconds` of wall time, whatever its speed: the speed-accuracy
    study (toolkit/study.py) with one time budget. Its calibration turns the time into a sample
    count per technique (mlt renders it as one run of its chains, paying its start once).
    Returns {technique: {"spp", "seconds", "rmse", "rmse_hard_pixels"}} against the scene's
    reference: the first repetition's RMSE (over the 10% hardest pixels for the last)."""
    from .study import study
    report = study(scene, list(techniques), budgets=[seconds], repeats=repeats, resolution=resolution, seed=seed,
                   device=device, bvh=bvh)
    out = {}
    for name in techniques:
        run = report["runs"][name]
        point, hard = run["points"][0], run["hard"]["points"][0]
        out[name] = {"spp": point["spp"], "seconds": point["seconds"][0], "rmse": point["rmse_each"][0],
                     "rmse_hard_pixels": hard["rmse_each"][0]}
    return out


def hard_pixels(ref, ref_err, fraction=0.1):
    """The pixels that are hardest for a path tracer: the `fraction` with the largest relative
    standard error in the reference (itself a path-traced render: Mitsuba's path integrator).
    In cornell_spheres these are the caustics and the light seen through the spheres."""
    rel = (ref_err / np.maximum(ref, 1e-6)).mean(-1)
    rel[ref.mean(-1) <= 0] = 0.0
    return rel >= np.quantile(rel, 1.0 - fraction)


def family(name):
    """"pt", "bdpt" or "mlt": the family of a technique or variant name (Technique.family)."""
    return get_technique(name)[0].family


def format_equal_time(report, seconds):
    lines = [f"equal time (~{seconds:g} s each): RMSE against the reference, over the whole image and over "
             f"the 10% pixels hardest for a path tracer (largest relative error in the reference: caustics)"]
    for name, row in report.items():
        lines.append(f"  {name:<30}{row['spp']:>7} spp {row['seconds']:>7.2f} s   RMSE {row['rmse']:.5f}"
                     f"   hard pixels {row['rmse_hard_pixels']:.5f}")
    for key, label in (("rmse", "whole image"), ("rmse_hard_pixels", "hard pixels")):
        pt = [r[key] for n, r in report.items() if family(n) == "pt"]
        bd = [r[key] for n, r in report.items() if family(n) == "bdpt"]
        if pt and bd:
            lines.append(f"  best BDPT / best PT RMSE, {label}: {min(bd) / min(pt):.2f}")
    for name, row in report.items():
        if family(name) == "mlt":
            for other in ("pt", "bdpt"):
                rows = [r["rmse"] for n, r in report.items() if family(n) == other]
                if rows:
                    lines.append(f"  {name} / best {other.upper()} RMSE, whole image: {row['rmse'] / min(rows):.2f}"
                                 f" ({'MLT wins' if row['rmse'] < min(rows) else 'MLT loses'})")
    pt = {n: r for n, r in report.items() if family(n) == "pt"}
    bd = {n: r for n, r in report.items() if family(n) == "bdpt"}
    if pt and bd:
        # Squared error x samples does not depend on the time spent: what one sample is worth.
        p_name = min(pt, key=lambda n: pt[n]["rmse"])
        b_name = min(bd, key=lambda n: bd[n]["rmse"])
        p, b = pt[p_name], bd[b_name]
        cost = (b["seconds"] / b["spp"]) / (p["seconds"] / p["spp"])
        worth = (p["rmse"] ** 2 * p["spp"]) / (b["rmse"] ** 2 * b["spp"])
        lines.append(f"  one {b_name} sample costs {cost:.1f} {p_name} samples here and is worth {worth:.1f} of them "
                     f"(squared error x samples, whole image): BDPT wins at equal time where worth > cost")
    return "\n".join(lines)


def format_bench(report):
    base = next(iter(report["techniques"]))
    lines = [f"bench: {report['scene']} {report['resolution'][0]}x{report['resolution'][1]}, {report['spp']} spp, "
             f"median of {report['repeats']} interleaved runs on {report['device']}, {report['bvh']} BVH"]
    if not report["gpu"]:
        lines.append("No GPU here: these figures describe a CPU, where idle SIMD lanes cost little; "
                     "the SIMD-efficiency counters (python -m toolkit compare) are what predict GPU behaviour.")
    lines.append(f"{'technique':<38}{'samples/s':>12}{'ratio to ' + base:>22}")
    for name, row in report["techniques"].items():
        lines.append(f"{name:<38}{row['samples_per_second']:>12,.0f}{row[f'ratio_to_{base}']:>22.2f}")
    return "\n".join(lines)
