"""`python -m toolkit bench`: samples/s of each technique and the ratios between them, measured
in one run with interleaved repetitions (technique A, B, C, A, B, C, ...) and their medians,
so a slow moment of the machine does not favour one technique. SIMD counters are off here.
"""
import statistics

from toolkit.api import as_scene, render
from toolkit.core.render_options import with_fields
from toolkit.opencl.device import get_queue
from toolkit.opencl.device_model import is_gpu
from toolkit.techniques import family


DEFAULT = ("pt_naive", "pt_inplace_regen", "pt_compact_regen", "pt_compact_regen/multipass",
           "bdpt_naive_connect", "bdpt_parallel_connect", "bdpt_parallel_connect/direct_scatter")


def bench(scene=None, techniques=DEFAULT, options=None, repeats=3, lanes=(None,), **fields):
    """Samples/s of each technique and the ratios to the first, medians of interleaved runs.
    `options`: a RenderOptions for the renders, with any of its fields as keywords on top, as
    toolkit.render takes them; its spp is the path tracers' (an eighth for BDPT and mlt), its
    resolution None is 128x128 here, and the SIMD counters are off. `lanes`: the SIMD-lanes settings
    to run each technique with ("on", "off"; None: the default); with two, every technique runs both
    ways, interleaved, and each row is named "technique [lanes on]" and has its ratio to the same
    technique with lanes off."""
    options = with_fields(options, **fields)
    options = with_fields(options, resolution=options.resolution or (128, 128))
    scene = as_scene(scene)
    rows = [(name, setting) for name in techniques for setting in lanes]

    def spp_of(name):
        # Bidirectional samples (and Metropolis mutations, each one) cost ~10x more: an eighth of
        # the budget keeps the runs comparable in length.
        return max(1, options.spp // 8) if family(name) in ("bdpt", "mlt") else options.spp

    rates, stats = interleaved_rates(scene, rows, spp_of, repeats, options)
    device_name = next(iter(stats.values()))["device"]
    widths = {row: {k: st[k] for k in ("lanes", "vector_width", "vector_widths")} for row, st in stats.items()}
    median = {row: statistics.median(v) for row, v in rates.items()}
    base = techniques[0]
    report = {}
    for name, setting in rows:
        off = (name, "off") if (name, "off") in median else None
        report[_row_name(name, setting, len(lanes))] = {
            "technique": name, "samples_per_second": median[(name, setting)], "runs": rates[(name, setting)],
            f"ratio_to_{base}": median[(name, setting)] / median[(base, setting)], **widths[(name, setting)],
            **({"ratio_to_lanes_off": median[(name, setting)] / median[off]} if off and setting == "on" else {})}
    # Whether the device measured is a GPU (Oclgrind, which claims every device type, is not):
    # on a CPU the caveat of format_bench applies.
    return {"scene": scene.name, "device": device_name, "gpu": is_gpu(get_queue(options.device).device),
            "spp": options.spp, "bvh": options.bvh, "general": options.general,
            "resolution": list(options.resolution), "repeats": repeats, "lanes": list(lanes), "techniques": report}


def interleaved_rates(scene, rows, spp_of, repeats, options, technique_options=None):
    """Samples/s of each (technique, lanes setting) in `rows`, in interleaved runs (A, B, C, A, B,
    C, ...), so a slow moment of the machine hits every row; a warm-up render of each row first,
    so no kernel build or BVH is timed. `spp_of(technique)`: its samples per pixel; `options`: the
    RenderOptions of every render (run r adds r to its seed; the SIMD counters are off);
    `technique_options`: {technique: its options}. Returns ({row: [samples/s per run]}, {row: its
    last render's stats})."""
    technique_options = technique_options or {}

    def options_of(name, setting, **fields):
        return with_fields(options, count_simd=False, lanes=setting,
                           technique_options=technique_options.get(name, {}), **fields)

    for name, setting in rows:
        render(scene, name, options_of(name, setting, spp=1, resolution=(16, 16)))
    rates, stats = {row: [] for row in rows}, {}
    for r in range(repeats):
        for name, setting in rows:
            result = render(scene, name, options_of(name, setting, spp=spp_of(name), seed=options.seed + r))
            rates[(name, setting)].append(result.stats["samples_per_second"])
            stats[(name, setting)] = result.stats
    return rates, stats


def _row_name(name, setting, settings):
    return f"{name} [lanes {setting}]" if settings > 1 else name


def format_bench(report):
    base = next(iter(report["techniques"].values()))["technique"]
    lines = [f"bench: {report['scene']} {report['resolution'][0]}x{report['resolution'][1]}, {report['spp']} spp, "
             f"median of {report['repeats']} interleaved runs on {report['device']}, {report['bvh']} BVH"]
    if not report["gpu"]:
        lines.append("Measured on a CPU, not a GPU: these figures describe a CPU, where idle SIMD lanes cost little; "
                     "the SIMD-efficiency counters (python -m toolkit compare) are what predict GPU behaviour.")
    both = any("ratio_to_lanes_off" in row for row in report["techniques"].values())
    lines.append(f"{'technique':<52}{'samples/s':>12}{'ratio to ' + base:>26}{'lanes':>12}"
                 + (f"{'on / off':>10}" if both else ""))
    for name, row in report["techniques"].items():
        lanes = row.get("lanes") or "-"
        if row.get("vector_width"):
            lanes += f" ({row['vector_width']})"
        lines.append(f"{name:<52}{row['samples_per_second']:>12,.0f}{row[f'ratio_to_{base}']:>26.2f}{lanes:>12}"
                     + (f"{row['ratio_to_lanes_off']:>10.2f}" if "ratio_to_lanes_off" in row else ""))
    lines.append("lanes: the setting, with the widest vector the compiler reported in its build log "
                 "(1: no kernel vectorized); ratios to " + base + " are within one lanes setting")
    return "\n".join(lines)
