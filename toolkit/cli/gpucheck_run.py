"""`python -m toolkit gpucheck` (the command: gpucheck.py): one run that checks and measures the
toolkit on a device (a GPU when there is one; it runs the same on a CPU) and writes one report,
text and JSON. It uses both measure/ and verify/, which are siblings, so it lives on the floor
above them:

1. the device, its warp width W and the stream and pool sizes chosen for it (toolkit/opencl/device.py,
   toolkit/opencl/work_sizes.py);
2. same image: the techniques of each family, work-group sizes 32/64/256, a small stream and
   pool against the device's, and other OpenCL implementations agree to float rounding on the
   same samples (toolkit/verify/same_image.py);
3. our BVH traversal against Embree (toolkit/verify/crosscheck.py): no unexplained disagreement;
4. `bench` of every technique (toolkit/measure/bench.py): samples/s, and the talk's two ratios, stream
   over in-place path tracing (talk: 1.2x) and parallel over naive BDPT connect (talk: 1.15x);
5. `compare` with the SIMD-efficiency figures (toolkit/measure/compare.py);
6. GPU against CPU where the machine has both (talk: a GPU 8-18x a CPU);
7. time per phase (kernel) of the four techniques behind the talk's two ratios, beside their
   SIMD efficiency (toolkit/measure/phases.py): where a ratio falls short, which phase costs;
8. the host meter (toolkit/measure/host_meter.py): per technique, what the host spends per sample
   (CPU time, bytes read back and written, blocking reads, launches) and the kernels' share of the
   wall time, at the device's own sizes;
9. without --fast, samples/s against the stream size, the pool size and MLT's chain count, from
   a sixteenth of the device's choice to twice it: whether the chosen sizes fill the device.

Step 2 also compares with CPU reference images carried from another machine, where given
(toolkit/verify/cpu_references.py: a GPU machine without a CPU runtime). Checks 2, 3 and 5 are correctness: any failure makes the exit code 1. The ratios are measured
and reported against the talk's figures, never asserted (a CPU is not a GPU).

The budgets follow the device: every render holds several samples per slot of the stream or
pool (`samples_per_slot`), so a GPU's larger streams regenerate as a CPU's do. `--fast` uses tiny
renders (the test suite runs it on PoCL).
"""
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
import pyopencl as cl

from toolkit import api
from toolkit.api import as_scene
from toolkit.core.scene import bundled_scene_dir
from toolkit.core.validate import InputError, writable_file
from toolkit.measure.bench import bench
from toolkit.measure.compare import compare
from toolkit.measure.host_meter import HOST_DEFAULT, format_host_meter, host_meter
from toolkit.opencl import device as devices
from toolkit.opencl.device_model import device_warp_width
from toolkit.opencl.work_sizes import device_work_sizes
from toolkit.measure.phases import phase_rows
from toolkit.verify import cpu_references
from toolkit.verify.crosscheck import compare_with_embree
from toolkit.verify.same_image import Check, same_image_checks

# The talk's GPU figures (van Antwerpen, HPG 2011) and the issue's GPU target.
TALK_RATIOS = {"stream PT / in-place PT": ("pt_compact_regen", "pt_inplace_regen", 1.20),
               "parallel / naive BDPT connect": ("bdpt_parallel_connect", "bdpt_naive_connect", 1.15)}
GPU_OVER_CPU_TARGET = 10.0
BENCH_TECHNIQUES = ("pt_naive", "pt_inplace_regen", "pt_compact_regen", "pt_compact_regen/multipass",
                    "bdpt_naive_connect", "bdpt_parallel_connect", "bdpt_parallel_connect/direct_scatter", "mlt")
PHASE_TECHNIQUES = ("pt_inplace_regen", "pt_compact_regen", "bdpt_naive_connect", "bdpt_parallel_connect")
SWEEP_FACTORS = (1 / 16, 1 / 8, 1 / 4, 1 / 2, 1, 2)     # of the device's stream size, pool size, chain count
COMPARE_TECHNIQUES = ("pt_naive", "pt_inplace_regen", "pt_compact_regen", "bdpt_naive_connect",
                      "bdpt_parallel_connect")
FAST = {"same_resolution": (16, 16), "same_spp": 8, "rays": 2000, "bench_resolution": (32, 32), "bench_spp": 8,
        "repeats": 1, "compare_resolution": (24, 24), "compare_spp": 8, "scenes": ("cornell_box",),
        "host_resolution": (32, 32), "host_spp": 4}


def side_for(samples, spp, multiple=16):
    """The side of a square image that holds `samples` at `spp`, rounded up to `multiple`."""
    return multiple * math.ceil(math.sqrt(samples / spp) / multiple)


def settings(sizes, fast):
    """Render sizes for this device: FAST, or budgets of 8 samples per stream slot (bench, compare)
    and 2 per slot (same image), at the bench's and compare's usual spp."""
    if fast:
        return dict(FAST)
    per_slot = max(sizes.stream_size / 8, sizes.pool_size)     # PT at 8 spp, BDPT at 1
    same = side_for(2 * 8 * per_slot, 8)
    return {"same_resolution": (same, same), "same_spp": 8, "rays": 100_000,
            "bench_resolution": (side_for(8 * sizes.stream_size, 16),) * 2, "bench_spp": 16, "repeats": 3,
            "compare_resolution": (side_for(8 * sizes.stream_size, 64),) * 2, "compare_spp": 64,
            "scenes": ("cornell_box", "cornell_spheres"),
            # the host meter's (bench --host): path tracers at 16 and 64 spp, BDPT and mlt at 4 and 16
            "host_resolution": (256, 256), "host_spp": 16}


def run(device=None, fast=False, out_dir="out/gpucheck", log=None, cpu_reference_folder=None, save=None):
    """Run every step; returns the report (a dict, see format_report). `cpu_reference_folder`:
    CPU images to compare with (cpu_references.py). `save(report)` is called after each step with
    the report so far, so a run stopped by a time limit leaves what it measured."""
    log = log or (lambda text: print(f"gpucheck: {text}", file=sys.stderr, flush=True))
    save = save or (lambda report: None)
    start = time.perf_counter()
    queue = devices.get_queue(device)
    dev = queue.device
    sizes = device_work_sizes(dev)
    s = settings(sizes, fast)
    report = {"device": _device_report(dev, sizes), "fast": fast, "complete": False, "checks": [], "passed": True,
              "settings": {k: list(v) if isinstance(v, tuple) else v for k, v in s.items()}}
    checks = []

    def step_done():
        report["checks"] = [{"step": step, "name": c.name, "passed": c.passed, "detail": c.detail,
                             "figures": c.figures} for step, c in checks]
        report["passed"] = all(c.passed for _, c in checks)
        report["seconds"] = time.perf_counter() - start
        save(report)

    scenes = {name: as_scene(bundled_scene_dir(name)) for name in s["scenes"]}
    box = scenes["cornell_box"]
    checks += [("same image", check) for check in _same_image_step(dev, box, device, s, log)]
    checks += [("CPU reference", check) for check in _cpu_reference_step(cpu_reference_folder, device, log)]
    step_done()
    checks += [("Embree", check) for check in _embree_step(scenes, queue, s, fast, log)]
    step_done()

    res = s["bench_resolution"]
    log(f"[3/5] bench: {len(BENCH_TECHNIQUES)} techniques, {res[0]}x{res[1]}, {s['bench_spp']} spp, "
        f"{s['repeats']} repeat(s)")
    report["bench"] = bench(box, BENCH_TECHNIQUES, spp=s["bench_spp"], resolution=res, repeats=s["repeats"],
                            device=device)
    rates = {name: row["samples_per_second"] for name, row in report["bench"]["techniques"].items()}
    report["ratios"] = {label: {"ratio": rates[a] / rates[b], "talk": talk, "of": f"{a} / {b}"}
                        for label, (a, b, talk) in TALK_RATIOS.items()}
    step_done()
    report["compare"], compare_checks = _compare_step(box, device, s, out_dir, fast, log)
    checks += [("compare", check) for check in compare_checks]
    step_done()

    log("[5/5] GPU against CPU")
    report["gpu_vs_cpu"] = gpu_vs_cpu(dev, report["device"]["gpu"], report["bench"], s, box, log)
    step_done()
    report["phases"] = _phase_step(box, device, s, log)
    step_done()
    res = s["host_resolution"]
    log(f"[+] host meter: {', '.join(HOST_DEFAULT)}, {res[0]}x{res[1]}, N = {s['host_spp']} spp (BDPT and mlt "
        f"{max(1, s['host_spp'] // 4)}) and 4N")
    report["host_meter"] = host_meter(box, HOST_DEFAULT, spp=s["host_spp"], resolution=res, device=device)
    step_done()
    if not fast:
        report["sweep"] = _sweep_step(box, device, sizes, s, log)
    report["complete"] = True
    step_done()
    return report


def _cpu_reference_step(folder, device, log):
    """Step 2, continued: this device against CPU images rendered elsewhere (none: no checks)."""
    if folder is None:
        return []
    log(f"[1/5] CPU reference images from {folder}")
    return cpu_references.checks(folder, device, log=lambda t: log(f"      {t}"))


def _phase_step(box, device, s, log):
    """Time per kernel of the techniques behind the talk's ratios, with each phase's SIMD
    efficiency, from one render each at the bench's size: {technique: {seconds, rows}}."""
    res = s["bench_resolution"]
    log(f"[+] time per phase: {', '.join(PHASE_TECHNIQUES)}, {res[0]}x{res[1]}")
    found = {}
    for name in PHASE_TECHNIQUES:
        spp = max(1, s["bench_spp"] // 8) if name.startswith("bdpt") else s["bench_spp"]
        stats = api_render(box, name, spp, res, device, time_phases=True).stats
        found[name] = {"seconds": stats["seconds"], "samples_per_second": stats["samples_per_second"],
                       "rows": phase_rows(stats)}
    return found


def _sweep_step(box, device, sizes, s, log):
    """Samples/s against the stream size (pt_compact_regen), the pool size (bdpt_parallel_connect)
    and the chain count (mlt), SWEEP_FACTORS of the device's choice, at budgets of 8 PT samples
    (4 BDPT samples) per slot of the largest size: {option: {"chosen", "rows": [(size, rate)]}}."""
    found = {}
    largest = max(SWEEP_FACTORS)
    for technique, option, chosen, spp, per_slot in (
            ("pt_compact_regen", "stream_size", sizes.stream_size, 16, 8),
            ("bdpt_parallel_connect", "pool_size", sizes.pool_size, 2, 4),
            ("mlt", "chains", sizes.pool_size, 2, 4)):
        side = side_for(per_slot * largest * chosen, spp)
        log(f"[+] sweep: {technique} {option} {', '.join(f'{int(chosen * f):,}' for f in SWEEP_FACTORS)}; "
            f"{side}x{side}, {spp} spp")
        rows = []
        for factor in SWEEP_FACTORS:
            size = max(256, int(chosen * factor) // 256 * 256)
            try:
                stats = api_render(box, technique, spp, (side, side), device, options={option: size},
                                   count_simd=False).stats
                rows.append({"size": size, "samples_per_second": stats["samples_per_second"],
                             "seconds": stats["seconds"]})
            except InputError as error:      # a size that does not fit the device: say so, go on
                rows.append({"size": size, "error": str(error)})
        found[option] = {"technique": technique, "chosen": chosen, "resolution": [side, side], "spp": spp,
                         "rows": rows}
    return found


def api_render(scene, technique, spp, resolution, device, **kwargs):
    return api.render(scene, technique=technique, spp=spp, seed=0, resolution=resolution, device=device, **kwargs)


def _device_report(dev, sizes):
    """Step 1: the device, its warp width and the work sizes chosen for it."""
    width, why = device_warp_width(dev)
    return {"name": devices.describe(dev), "implementation": devices.describe_implementation(dev),
            "gpu": _is_gpu(dev), "compute_units": dev.max_compute_units, "warp_width": width,
            "warp_width_source": why, "stream_size": sizes.stream_size, "pool_size": sizes.pool_size,
            "work_sizes_source": sizes.why}


def _same_image_step(dev, box, device, s, log):
    """Step 2: the same image from every technique and setting, here and on the other implementations."""
    # Other OpenCL implementations to compare images with (Oclgrind, a simulator, left out).
    others = [c for c in devices.candidates() if c.usable and c.rank[0] < 4 and c.device.int_ptr != dev.int_ptr]
    log(f"[1/5] same image on {devices.describe(dev)} "
        f"({s['same_resolution'][0]}x{s['same_resolution'][1]}; also on {len(others)} other implementation(s))")
    return same_image_checks(box, device, s["same_resolution"], s["same_spp"],
                             others=[(c.selector, c.implementation) for c in others], log=lambda t: log(f"      {t}"))


def _embree_step(scenes, queue, s, fast, log):
    """Step 3: our traversal against Embree's on random rays, both BVHs (skipped without embreex)."""
    log(f"[2/5] Embree cross-check ({s['rays']:,} random rays per scene and BVH)")
    try:
        import embreex  # noqa: F401  (an optional check: is Embree here at all?)
    except ImportError:
        return [Check("Embree cross-check", True, "skipped: embreex is not installed")]
    checks = []
    for name, scene in scenes.items():
        for bvh in ("wide", "binary"):
            f = compare_with_embree(scene, n_random=s["rays"], resolution=32 if fast else None, queue=queue, bvh=bvh)
            unexplained = f["unexplained"] + f["any_unexplained"]
            checks.append(Check(f"{name}, {bvh} BVH: {f['rays']:,} rays", unexplained == 0,
                                f"{f['unexplained']} closest-hit and {f['any_unexplained']} any-hit "
                                f"disagreements unexplained ({f['excused']} excused)",
                                {k: f[k] for k in ("rays", "excused", "unexplained", "any_unexplained")}))
    return checks


def _compare_step(box, device, s, out_dir, fast, log):
    """Step 5: `compare`'s SIMD figures, each within (0, 1] and every pixel finite: (figures, checks)."""
    res = s["compare_resolution"]
    log(f"[4/5] compare with SIMD figures: {res[0]}x{res[1]}, {s['compare_spp']} spp")
    table = compare(box, list(COMPARE_TECHNIQUES), s["compare_spp"], resolution=res, device=device,
                    out_dir=out_dir, plots=not fast)
    figures = {name: {k: row[k] for k in ("samples_per_second", "simd_efficiency", "rmse", "nonfinite")}
               for name, row in table.items()}
    checks = []
    for name, row in table.items():
        efficiency = row["simd_efficiency"]
        sane = row["nonfinite"] == 0 and all(0.0 < v <= 1.0 for v in efficiency.values())
        checks.append(Check(f"{name}: SIMD figures", sane, f"overall {efficiency.get('overall', float('nan')):.1%}, "
                                                           f"{row['nonfinite']} non-finite pixels"))
    return figures, checks


def _is_gpu(device):
    return bool(device.type & cl.device_type.GPU) and not device.type & cl.device_type.CPU


def gpu_vs_cpu(dev, is_gpu, bench_report, s, scene, log):
    """Samples/s of the best path tracer and BDPT on a GPU and on a CPU, when both exist."""
    usable = [c for c in devices.candidates() if c.usable and c.rank[0] < 4]
    gpus = [c for c in usable if _is_gpu(c.device)]
    cpus = [c for c in usable if not _is_gpu(c.device)]
    if not gpus or not cpus:
        kinds = ", ".join(f"{c.implementation} ({'GPU' if _is_gpu(c.device) else 'CPU'})" for c in usable)
        return {"measured": False,
                "note": f"{'only GPUs' if gpus else 'only a CPU'} here ({kinds}): no GPU against CPU figure"}
    other = cpus[0] if is_gpu else gpus[0]
    log(f"      bench on {devices.describe(other.device)}")
    names = ("pt_compact_regen", "bdpt_parallel_connect")
    there = bench(scene, names, spp=s["bench_spp"], resolution=s["bench_resolution"], repeats=s["repeats"],
                  device=other.selector)
    here = {n: bench_report["techniques"][n]["samples_per_second"] for n in names}
    away = {n: there["techniques"][n]["samples_per_second"] for n in names}
    gpu, cpu = (here, away) if is_gpu else (away, here)
    return {"measured": True, "cpu": cpus[0].implementation if is_gpu else devices.describe_implementation(dev),
            "gpu": devices.describe_implementation(dev) if is_gpu else gpus[0].implementation,
            "ratios": {n: gpu[n] / cpu[n] for n in names}, "target": GPU_OVER_CPU_TARGET}


def format_report(r):
    """The report as text; a report saved part-way (r["complete"] false) says where it stopped."""
    d = r["device"]
    lines = [f"gpucheck{' --fast' if r['fast'] else ''}: {d['name']}; {d['implementation']}",
             f"  {'GPU' if d['gpu'] else 'CPU'}, {d['compute_units']} compute units; SIMD counters: warps of "
             f"{d['warp_width']} ({d['warp_width_source']})",
             f"  in flight: stream {d['stream_size']:,} paths, BDPT pool {d['pool_size']:,} samples "
             f"({d['work_sizes_source']})", "", "Checks:"]
    for c in r["checks"]:
        lines.append(f"  {'PASS' if c['passed'] else 'FAIL'}  {c['step']}: {c['name']}: {c['detail']}")
    if "bench" in r:
        lines += _bench_lines(r, d)
    if "compare" in r:
        lines.append("SIMD efficiency (compare):")
        for name, row in r["compare"].items():
            eff = row["simd_efficiency"]
            lines.append(f"  {name:<26} overall {eff.get('overall', float('nan')):6.1%}  "
                         + ", ".join(f"{k} {v:.1%}" for k, v in eff.items() if k != "overall"))
    g = r.get("gpu_vs_cpu")
    if g and g["measured"]:
        lines.append(f"GPU ({g['gpu']}) against CPU ({g['cpu']}): "
                     + ", ".join(f"{n} {x:.1f}x" for n, x in g["ratios"].items()) + f" (target >= {g['target']:g}x)")
    elif g:
        lines.append(f"GPU against CPU: {g['note']}")
    if "phases" in r:
        lines += _phase_lines(r["phases"])
    if "host_meter" in r:
        lines += ["", format_host_meter(r["host_meter"])]
    if "sweep" in r:
        lines += _sweep_lines(r["sweep"])
    failed = sum(not c["passed"] for c in r["checks"])
    verdict = "PASSED" if r["passed"] else f"FAILED: {failed} check(s)"
    if not r.get("complete", True):
        verdict = f"INCOMPLETE (stopped part-way; so far {verdict})"
    lines.append(f"{verdict} in {r.get('seconds', 0):.0f} s")
    return "\n".join(lines)


def _bench_lines(r, d):
    b = r["bench"]
    lines = ["", f"bench: {b['scene']} {b['resolution'][0]}x{b['resolution'][1]}, {b['spp']} spp (BDPT and mlt: "
             f"{max(1, b['spp'] // 8)}), median of {b['repeats']}"]
    lines += [f"  {name:<40}{row['samples_per_second']:>14,.0f} samples/s" for name, row in b["techniques"].items()]
    lines.append("Stream against in-place (the talk's GPU figures):")
    for label, row in r["ratios"].items():
        verdict = "reaches" if row["ratio"] >= row["talk"] else "below"
        lines.append(f"  {label} ({row['of']}): {row['ratio']:.2f}x, talk {row['talk']:.2f}x ({verdict})")
    if not d["gpu"]:
        lines.append("  (on a CPU: idle SIMD lanes cost little there, so these ratios say little about a GPU)")
    return lines


def _phase_lines(phases):
    lines = ["Time per phase (ms; SIMD efficiency of the phase's lanes, traversal's in brackets):"]
    for name, found in phases.items():
        lines.append(f"  {name}: {found['seconds'] * 1e3:,.1f} ms, {found['samples_per_second']:,.0f} samples/s")
        for row in found["rows"]:
            eff = "" if row["simd_efficiency"] is None else f"  {row['simd_efficiency']:.1%}"
            if row["traversal_efficiency"] is not None:
                eff += f" [{row['traversal_efficiency']:.1%}]"
            lines.append(f"    {row['kernel']:<34}{row['launches']:>6} x {row['ms']:>10,.2f} ms {row['share']:>6.1%}{eff}")
    return lines


def _sweep_lines(sweep):
    lines = ["Samples/s against the work in flight (the device's choice marked *):"]
    for option, found in sweep.items():
        lines.append(f"  {found['technique']}, {option} ({found['resolution'][0]}x{found['resolution'][1]}, "
                     f"{found['spp']} spp):")
        for row in found["rows"]:
            mark = "*" if row["size"] == found["chosen"] else " "
            figure = f"{row['samples_per_second']:>14,.0f} samples/s" if "samples_per_second" in row else row["error"]
            lines.append(f"   {mark}{row['size']:>10,}  {figure}")
    return lines


def report_path(out):
    """`out` checked before any work: a .txt file (the JSON goes beside it) in a folder that
    accepts new files; else an InputError that names the problem."""
    path = Path(out)
    if path.suffix.lower() != ".txt":
        raise InputError(f"--out {path}: the report is text; give a .txt name (its JSON goes beside it)")
    return writable_file(path)


def write_report(report, out):
    """The text at `out` and the JSON beside it (same name, .json); returns both paths. Each file
    is written whole beside its place, then moved there: a failed write leaves the old one."""
    text_path = Path(out)
    json_path = text_path.with_suffix(".json")
    text_path.parent.mkdir(parents=True, exist_ok=True)
    _replace(text_path, format_report(report) + "\n")
    _replace(json_path, json.dumps(report, indent=1, default=_plain) + "\n")
    return text_path, json_path


def _replace(path, text):
    partial = path.with_name(f".{path.name}.partial")
    partial.write_text(text)
    os.replace(partial, path)


def _plain(x):
    return x.item() if isinstance(x, np.generic) else str(x)
