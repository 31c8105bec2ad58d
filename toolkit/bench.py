"""`python -m toolkit bench`: samples/s of each technique and the ratios between them, measured
in one run with interleaved repetitions (technique A, B, C, A, B, C, ...) and their medians,
so a slow moment of the machine does not favour one technique. SIMD counters are off here.
"""
import statistics

from .api import as_scene, render
from .device import has_gpu


DEFAULT = ("pt_naive", "pt_inplace_regen", "pt_compact_regen", "pt_compact_regen/multipass",
           "bdpt_naive_connect", "bdpt_parallel_connect", "bdpt_parallel_connect/direct_scatter")


def bench(scene=None, techniques=DEFAULT, spp=16, resolution=(128, 128), repeats=3, seed=0, device=None):
    scene = as_scene(scene)
    for name in techniques:   # warm-up: kernel builds and BVH outside the timings
        render(scene, technique=name, spp=1, resolution=(16, 16), device=device, count_simd=False)
    rates = {name: [] for name in techniques}
    device_name = None
    for r in range(repeats):
        for name in techniques:
            # Bidirectional samples cost ~10x more: an eighth of the budget keeps the runs comparable in length.
            n = max(1, spp // 8) if name.startswith("bdpt") else spp
            result = render(scene, technique=name, spp=n, seed=seed + r, resolution=resolution,
                            device=device, count_simd=False)
            rates[name].append(result.stats["samples_per_second"])
            device_name = result.stats["device"]
    median = {name: statistics.median(v) for name, v in rates.items()}
    base = techniques[0]
    return {"scene": scene.name, "device": device_name, "gpu": has_gpu(), "spp": spp,
            "resolution": list(resolution), "repeats": repeats,
            "techniques": {name: {"samples_per_second": median[name], "runs": rates[name],
                                  f"ratio_to_{base}": median[name] / median[base]} for name in techniques}}


def format_equal_time(report, seconds):
    lines = [f"equal time (~{seconds:g} s each): RMSE against the reference, over the whole image and over "
             f"the 10% pixels hardest for a path tracer (largest relative error in the reference: caustics)"]
    for name, row in report.items():
        lines.append(f"  {name:<30}{row['spp']:>7} spp {row['seconds']:>7.2f} s   RMSE {row['rmse']:.5f}"
                     f"   hard pixels {row['rmse_hard_pixels']:.5f}")
    for key, label in (("rmse", "whole image"), ("rmse_hard_pixels", "hard pixels")):
        pt = [r[key] for n, r in report.items() if n.startswith("pt")]
        bd = [r[key] for n, r in report.items() if n.startswith("bdpt")]
        if pt and bd:
            lines.append(f"  best BDPT / best PT RMSE, {label}: {min(bd) / min(pt):.2f}")
    pt = {n: r for n, r in report.items() if n.startswith("pt")}
    bd = {n: r for n, r in report.items() if n.startswith("bdpt")}
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
             f"median of {report['repeats']} interleaved runs on {report['device']}"]
    if not report["gpu"]:
        lines.append("No GPU here: these figures describe a CPU, where idle SIMD lanes cost little; "
                     "the SIMD-efficiency counters (python -m toolkit compare) are what predict GPU behaviour.")
    lines.append(f"{'technique':<38}{'samples/s':>12}{'ratio to ' + base:>22}")
    for name, row in report["techniques"].items():
        lines.append(f"{name:<38}{row['samples_per_second']:>12,.0f}{row[f'ratio_to_{base}']:>22.2f}")
    return "\n".join(lines)
