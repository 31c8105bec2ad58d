"""`python -m toolkit bench`: samples/s of each technique and the ratios between them, measured
in one run with interleaved repetitions (technique A, B, C, A, B, C, ...) and their medians,
so a slow moment of the machine does not favour one technique. SIMD counters are off here.
"""
import statistics

import numpy as np

from toolkit.api import as_scene, render
from toolkit.opencl.device import get_queue
from toolkit.opencl.device_model import is_gpu
from toolkit.techniques import family


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
    # Whether the device measured is a GPU (Oclgrind, which claims every device type, is not):
    # on a CPU the caveat of format_bench applies.
    return {"scene": scene.name, "device": device_name, "gpu": is_gpu(get_queue(device).device), "spp": spp,
            "bvh": bvh, "general": general, "resolution": list(resolution), "repeats": repeats,
            "techniques": {name: {"samples_per_second": median[name], "runs": rates[name],
                                  f"ratio_to_{base}": median[name] / median[base]} for name in techniques}}


def format_bench(report):
    base = next(iter(report["techniques"]))
    lines = [f"bench: {report['scene']} {report['resolution'][0]}x{report['resolution'][1]}, {report['spp']} spp, "
             f"median of {report['repeats']} interleaved runs on {report['device']}, {report['bvh']} BVH"]
    if not report["gpu"]:
        lines.append("Measured on a CPU, not a GPU: these figures describe a CPU, where idle SIMD lanes cost little; "
                     "the SIMD-efficiency counters (python -m toolkit compare) are what predict GPU behaviour.")
    lines.append(f"{'technique':<38}{'samples/s':>12}{'ratio to ' + base:>22}")
    for name, row in report["techniques"].items():
        lines.append(f"{name:<38}{row['samples_per_second']:>12,.0f}{row[f'ratio_to_{base}']:>22.2f}")
    return "\n".join(lines)
