"""Command line: `python -m toolkit {render,devices,...}`. See README.md for examples."""
import argparse
import json
import os
import sys
import warnings

import numpy as np
import pyopencl as cl

from toolkit.opencl import runtimes
from toolkit.opencl.device import (HOW_TO_GET_OPENCL, RANKING, NoOpenCLError, candidates, describe, has_gpu,
                                   pick_device)
from toolkit.opencl.device_model import device_warp_width
from toolkit.opencl.work_sizes import device_work_sizes


def _resolution(text):
    try:
        w, h = (int(x) for x in text.lower().split("x"))
        if w < 1 or h < 1:
            raise ValueError
        return w, h
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT like 64x64, got {text!r}") from None


def _number(text):
    """A float, checked for range later (validate.py), so the message names the limit."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def _whole(text):
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None


def _positive(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError("must be at least 1")
    return value


def build_parser():
    from toolkit.techniques import TECHNIQUES
    parser = argparse.ArgumentParser(prog="python -m toolkit", description=__doc__)
    parser.add_argument("--device", help="OpenCL device: P:D indices or a name part (overrides PYOPENCL_CTX)")
    parser.add_argument("--verbose", action="store_true", help="print every kernel build log in full")
    sub = parser.add_subparsers(dest="command", required=True)

    def bvh_option(p):
        p.add_argument("--bvh", choices=["binary", "wide"], default="wide",
                       help="wide: 4 children per node tested with float4 operations (SIMD inside one ray); "
                            "binary: the SAH BVH it is collapsed from (default wide)")

    def general_option(p):
        p.add_argument("--general", action="store_true",
                       help="build the general kernel (every material and feature compiled in) instead of "
                            "the one specialized to the scene; the same image (bench --specialization "
                            "measures the difference)")

    def device_option(p):
        # Also accepted after the command; SUPPRESS keeps a value given before it.
        p.add_argument("--device", default=argparse.SUPPRESS,
                       help="OpenCL device: P:D indices or a name part (overrides PYOPENCL_CTX)")

    p = sub.add_parser("render", help="render a scene with one technique")
    device_option(p)
    p.add_argument("scene", nargs="?", help="scene folder or scene.json (default: bundled cornell_box)")
    p.add_argument("--technique", default="pt_naive", choices=sorted(TECHNIQUES))
    p.add_argument("--spp", type=_positive, default=64, help="samples per pixel (default 64)")
    p.add_argument("--resolution", type=_resolution, help="WxH; keeps the scene's camera and field of view")
    p.add_argument("--seed", type=_whole, default=0, help="0 .. 2^32 - 1")
    p.add_argument("--out", help="output .exr (an sRGB .png is written beside it) or .png alone; default out/<scene>_<technique>.exr")
    p.add_argument("--json", action="store_true", help="print a JSON summary as the last line of stdout")
    p.add_argument("--no-progress", action="store_true")
    p.add_argument("--strategies", metavar="DIR",
                   help="bdpt_* only, instead of one image: an image per connection strategy (s, t), with and "
                        "without its MIS weight (Veach's figure 10.3), into DIR with strategies.json and a table "
                        "of each strategy's share of the image and of the variance")
    p.add_argument("--strategy-edges", type=_positive, default=5, metavar="K",
                   help="with --strategies: strategies of paths up to K edges get images, longer paths one "
                        "summed image (default 5)")
    bvh_option(p)
    general_option(p)

    sub.add_parser("devices", help="list OpenCL platforms and devices, and which one the toolkit picks")

    p = sub.add_parser("crosscheck", help="our BVH traversal against Embree: agreement figures")
    device_option(p)
    p.add_argument("scene", nargs="?", help="scene folder or scene.json (default: bundled cornell_box)")
    p.add_argument("--rays", type=_positive, default=100_000, help="random rays besides the camera rays")
    p.add_argument("--seed", type=_whole, default=0, help="0 .. 2^32 - 1")
    p.add_argument("--json", action="store_true")
    bvh_option(p)

    from toolkit.techniques import VARIANTS
    names = ", ".join([*sorted(TECHNIQUES), *VARIANTS])
    p = sub.add_parser("compare", help="several techniques side by side: time, SIMD efficiency, error")
    device_option(p)
    p.add_argument("scene", nargs="?", help="scene folder or scene.json (default: bundled cornell_box)")
    p.add_argument("--techniques", default="pt_naive,pt_inplace_regen,pt_compact_regen",
                   help=f"comma-separated, from: {names}")
    # 64x64 at 64 spp: a pass of 262,144 samples, eight per slot of the stream techniques'
    # 32,768, so their pools regenerate (at 8 spp each slot would hold one sample and
    # pt_inplace_regen would look like pt_naive); tutorial 2 uses the same budget.
    p.add_argument("--spp", type=_positive, default=64, help="samples per pixel (default 64)")
    p.add_argument("--resolution", type=_resolution, default=(64, 64), help="WxH (default 64x64)")
    p.add_argument("--seed", type=_whole, default=0, help="0 .. 2^32 - 1")
    p.add_argument("--warp-width", type=int, default=None, choices=[8, 16, 32, 64],
                   help="W of the SIMD-efficiency counters (default: the device's: 32 on NVIDIA and on a CPU, "
                        "64 on AMD, 16 on Intel GPUs; `devices` shows it)")
    p.add_argument("--json", action="store_true", help="print a JSON object as the last line of stdout")
    p.add_argument("--out", default="out/compare", help="folder for images and plots (default out/compare)")
    p.add_argument("--no-progress", action="store_true")
    bvh_option(p)
    general_option(p)

    p = sub.add_parser("bench", help="samples/s of each technique and their ratios, measured in one run")
    device_option(p)
    p.add_argument("scene", nargs="?", help="scene folder or scene.json (default: bundled cornell_box)")
    from toolkit.measure.bench import DEFAULT
    from toolkit.peers.mitsuba import PEER_DEFAULT
    p.add_argument("--techniques", help=f"comma-separated, from: {names} (default {','.join(DEFAULT)}; "
                                        f"with --peer mitsuba: {','.join(PEER_DEFAULT)})")
    p.add_argument("--spp", type=_positive, default=16, help="samples per pixel for path tracers (BDPT: an eighth)")
    p.add_argument("--resolution", type=_resolution, default=None,
                   help="WxH (default 128x128; with --equal-time 32x32, which every bundled reference averages to; "
                        "with --peer: the scene's own)")
    p.add_argument("--repeats", type=_positive, default=3)
    p.add_argument("--peer", choices=["embree", "mitsuba"],
                   help="instead: embree: closest-hit rays/s of our BVHs against embreex on the same rays; "
                        "mitsuba: Mitsuba 3's path integrator beside the toolkit (spp/s, variance per sample, "
                        "time to 5%% RMSE); needs pip install \".[peers]\"")
    p.add_argument("--equal-time", type=_number, metavar="SECONDS",
                   help="instead: render each technique for about SECONDS and compare RMSE against the reference")
    p.add_argument("--specialization", action="store_true",
                   help="instead: the kernels specialized to the scene against the general kernel, on SCENE or "
                        "every bundled scene: samples/s, uncached build time, binary size (default techniques "
                        "pt_naive,pt_compact_regen,bdpt_parallel_connect; resolution 64x64)")
    p.add_argument("--json", action="store_true")
    bvh_option(p)
    general_option(p)

    p = sub.add_parser("gpucheck", help="check and measure the toolkit on a device (a GPU if there is one): "
                                        "same-image tests, Embree cross-check, bench, compare; one report",
                       description="On the chosen device: the same-image checks, the Embree cross-check, bench of "
                                   "every technique (stream vs in-place ratios against the talk's) and compare with "
                                   "SIMD figures, GPU against CPU where both exist. Writes one report (text and "
                                   "JSON); exit code 1 when a correctness check fails.")
    device_option(p)
    p.add_argument("--fast", action="store_true", help="tiny renders (what the test suite runs)")
    p.add_argument("--out", default="out/gpucheck.txt",
                   help="the report (text); its JSON goes beside it as .json (default out/gpucheck.txt)")

    from toolkit.measure.study import DEFAULT_BUDGETS, DEFAULT_REPEATS, DEFAULT_TARGET, DEFAULT_TECHNIQUES
    p = sub.add_parser(
        "study", help="the speed-accuracy study: error (bias^2, variance) against time per technique or knob value",
        description="Error against time for each technique, or for each value of an accuracy knob, against the "
                    "scene's reference: MSE split into bias^2 and variance over independent repetitions, "
                    "efficiency 1/(MSE x time), the log-log slope of RMSE against time, the time to a relative "
                    "RMSE target, the same over the 10% hardest pixels, each with its standard error. Time budgets "
                    "are turned into sample counts by a short calibration of each run (the plan is in the JSON), "
                    "and each repetition has its own seed, so a study is reproducible. Prints a table; writes "
                    "study.json and plots to --out.")
    device_option(p)
    p.add_argument("scene", nargs="?", help="scene folder or scene.json (default: bundled cornell_box)")
    p.add_argument("--techniques", default=",".join(DEFAULT_TECHNIQUES),
                   help=f"comma-separated, from: {names} (default {','.join(DEFAULT_TECHNIQUES)})")
    p.add_argument("--budgets", default=",".join(f"{b:g}" for b in DEFAULT_BUDGETS), metavar="SECONDS,...",
                   help="seconds of rendering per repetition (default %(default)s); each becomes a sample count "
                        "per run by calibration (build and warm-up excluded and reported apart), so runs are "
                        "reproducible")
    p.add_argument("--spp-budgets", metavar="SPP,...",
                   help="instead of --budgets: fixed samples per pixel for every run, no calibration (to "
                        "reproduce a study's plan, or for tests)")
    p.add_argument("--repeats", type=_positive, default=DEFAULT_REPEATS,
                   help="independent repetitions per budget, each with its own seed (default %(default)s; "
                        "at least 2 to split bias^2 from variance, 3 for standard errors)")
    p.add_argument("--resolution", type=_resolution, default=(32, 32),
                   help="WxH (default 32x32, which every bundled reference averages to)")
    p.add_argument("--seed", type=_whole, default=0,
                   help="base seed: repetition r of budget k uses seed + k x repeats + r")
    p.add_argument("--knob", metavar="NAME=V1,V2,...",
                   help="sweep an accuracy knob for each technique: max_depth, rr_depth, clamp (scene integrator "
                        "settings; clamp=none,10), pass_spp, resolution (8x8,16x16), or a technique option such "
                        "as mlt's chains, start, large_step")
    p.add_argument("--target", type=_number, default=DEFAULT_TARGET,
                   help="relative RMSE target for the time-to-target figures (default %(default)s: 5%% of the "
                        "reference's mean)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the repetitions on an existing Dask cluster (tcp://host:8786); each worker uses its "
                        "own OpenCL device; needs pip install \".[cluster]\"")
    p.add_argument("--out", default="out/study", help="folder for study.json and the plots (default out/study)")
    p.add_argument("--json", action="store_true", help="print the report as JSON as the last line of stdout")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (calibration, then the renders)")
    p.add_argument("--specialization", action="store_true",
                   help="also measure the kernels specialized to the scene against the general kernel (every "
                        "material and feature compiled in) for the study's techniques: samples/s ratio, uncached "
                        "build time, binary size (bench --specialization does every bundled scene)")
    bvh_option(p)

    from toolkit.grading.grade import ASSIGNMENTS, TIME_LIMIT
    p = sub.add_parser("grade", help="grade a course assignment (tutorials/assignments/): score /100 per check")
    device_option(p)
    p.add_argument("assignment", choices=list(ASSIGNMENTS))
    p.add_argument("--kernel", nargs="+", metavar="PATH", help="your file(s), built in place of the toolkit's")
    p.add_argument("--solution", action="store_true", help="grade the toolkit's own kernel (the reference solution)")
    p.add_argument("--stub", action="store_true", help="print the assignment's starting file")
    p.add_argument("--json", action="store_true", help="one JSON line per graded file")
    p.add_argument("--time-limit", type=_number, default=TIME_LIMIT, metavar="SECONDS",
                   help=f"per check (default {TIME_LIMIT}); a kernel that runs longer loses the check")
    return parser


def _warning_line(message, category, filename, lineno, file=None, line=None):
    print(f"warning: {message}", file=sys.stderr)


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    from toolkit.opencl import program
    program.verbose = program.verbose or args.verbose
    from toolkit.opencl.device import NoOpenCLError
    from toolkit.opencl.program import KernelBuildError
    from toolkit.core.scene import SceneError
    shown = warnings.showwarning
    warnings.showwarning = _warning_line      # one "warning: ..." line, not file and source line
    try:
        if args.command == "devices":
            print(devices_report())
            return 0
        if args.command == "render":
            return cmd_render(args)
        if args.command == "compare":
            return cmd_compare(args)
        if args.command == "bench":
            return cmd_bench(args)
        if args.command == "crosscheck":
            return cmd_crosscheck(args)
        if args.command == "gpucheck":
            return cmd_gpucheck(args)
        if args.command == "study":
            return cmd_study(args)
        if args.command == "grade":
            from toolkit.grading.grade import cmd_grade
            return cmd_grade(args)
    except (NoOpenCLError, KernelBuildError) as error:
        # A compiler log and the list of devices with their fixes keep their lines.
        print(f"error: {error}", file=sys.stderr)
        return 2
    except (SceneError, ValueError, OSError) as error:
        print("error: " + " ".join(str(error).split()), file=sys.stderr)   # bad input: one line
        return 2
    finally:
        warnings.showwarning = shown
    return 1


def cmd_render(args):
    if args.strategies:
        return cmd_render_strategies(args)
    from toolkit.api import as_scene, render
    from toolkit.core.images import write_image
    from toolkit.measure.reference import reference_at, reference_problem, rmse
    from toolkit.core.validate import check_output
    if args.out:
        check_output(args.out)      # before the render: a bad --out must not cost its time
    scene = as_scene(args.scene)
    width, height = args.resolution or (scene.camera.width, scene.camera.height)
    out = check_output(args.out or f"out/{scene.name}_{args.technique}.exr")
    result = render(scene, technique=args.technique, spp=args.spp, seed=args.seed,
                    resolution=(width, height), device=args.device, progress=not args.no_progress, bvh=args.bvh,
                    general=args.general)
    written = write_image(out, result.image.astype(np.float32))
    stats = dict(result.stats, out=str(out))
    ref, _ = reference_at(scene, width, height)
    if ref is not None:
        stats["rmse"] = rmse(result.image, ref)
    problem = reference_problem(scene, width, height)
    simd = stats["simd_efficiency"]
    lines = [f"{stats['technique']} on {stats['scene']} {width}x{height}, {args.spp} spp: "
             f"{stats['seconds']:.2f} s, {stats['samples_per_second']:,.0f} samples/s on {stats['device']}",
             f"  image mean (linear RGB) {np.round(stats['mean'], 5).tolist()}, non-finite pixels "
             f"{stats['nonfinite']}, dropped samples {stats['nonfinite_samples']}",
             f"  SIMD efficiency (W={stats['warp_width']}, {stats['warp_width_source']}): "
             + ", ".join(f"{k} {v:.1%}" for k, v in simd.items())]
    for option in ("stream_size", "pool_size"):
        if option in stats:
            lines.append(f"  in flight: {option} {stats[option]:,} ({stats['work_sizes_source']})")
    if "rmse" in stats:
        lines.append(f"  RMSE against the reference {stats['rmse']:.5f}")
    elif problem:
        lines.append(f"  no RMSE: {problem}")
    lines.append("  wrote " + " and ".join(str(p) for p in written))
    print("\n".join(lines))
    if args.json:
        print(json.dumps(stats))
    return 0


def cmd_render_strategies(args):
    from toolkit.api import as_scene
    from toolkit.measure.strategies import format_strategies, render_strategies, write_strategies
    from toolkit.core.validate import check_output
    if args.general:
        raise ValueError("--strategies builds its own kernels; --general does not apply")
    scene = as_scene(args.scene)
    check_output(f"{args.strategies}/full.exr")     # before the render: a bad folder must not cost its time
    image, result = render_strategies(scene, args.technique, spp=args.spp, seed=args.seed,
                                      resolution=args.resolution, device=args.device, max_edges=args.strategy_edges,
                                      bvh=args.bvh, progress=not args.no_progress)
    report = write_strategies(args.strategies, image, result, scene.name, args.technique)
    print(format_strategies(report))
    print(f"  wrote {len(report['strategies'])} x 2 strategy images, longer_weighted.exr, full.exr and "
          f"strategies.json to {args.strategies}")
    if args.json:
        print(json.dumps(report))
    return 0


def _technique_list(text):
    from toolkit.techniques import get_technique
    names = [t.strip() for t in text.split(",") if t.strip()]
    for name in names:
        get_technique(name)   # raises a clear ValueError for an unknown name
    if not names:
        raise ValueError("no technique given")
    return names


def cmd_compare(args):
    from toolkit.measure.compare import compare, format_table
    table = compare(args.scene, _technique_list(args.techniques), args.spp, resolution=args.resolution,
                    seed=args.seed, warp_width=args.warp_width, out_dir=args.out, device=args.device,
                    progress=not args.no_progress, bvh=args.bvh, general=args.general)
    print(format_table(table))
    first = next(iter(table.values()))
    print("plots: " + ", ".join(first.get("plots", {}).values()))
    if args.json:
        print(json.dumps(table))
    return 0


def cmd_bench(args):
    from toolkit.measure.bench import DEFAULT, bench, format_bench
    from toolkit.measure.study import format_equal_time
    from toolkit.core.validate import finite_number, whole_number
    whole_number("bench.repeats", args.repeats, "--repeats")
    if args.peer:
        return cmd_bench_peer(args)
    if args.specialization:
        return cmd_bench_specialization(args)
    if args.equal_time is not None:
        finite_number("bench.equal_time", args.equal_time, "--equal-time")
        from toolkit.measure.study import equal_time
        scene = args.scene or "scenes/cornell_spheres"
        report = equal_time(scene, _technique_list(args.techniques or ",".join(DEFAULT)), args.equal_time,
                            resolution=args.resolution or (32, 32), device=args.device, bvh=args.bvh)
        print(format_equal_time(report, args.equal_time))
        if args.json:
            print(json.dumps(report))
        return 0
    report = bench(args.scene, tuple(_technique_list(args.techniques or ",".join(DEFAULT))), spp=args.spp,
                   resolution=args.resolution or (128, 128), repeats=args.repeats, device=args.device, bvh=args.bvh,
                   general=args.general)
    print(format_bench(report))
    if args.json:
        print(json.dumps(report))
    return 0


def cmd_bench_specialization(args):
    from toolkit.measure.specialization import DEFAULT_TECHNIQUES, format_specialization, measure_specialization
    techniques = _technique_list(args.techniques or ",".join(DEFAULT_TECHNIQUES))
    report = measure_specialization(args.scene, techniques, resolution=args.resolution or (64, 64), spp=args.spp,
                                    repeats=args.repeats, device=args.device, bvh=args.bvh,
                                    progress=lambda line: print(line, file=sys.stderr, flush=True))
    print(format_specialization(report))
    if args.json:
        print(json.dumps(report))
    return 0


def cmd_bench_peer(args):
    from toolkit.peers import mitsuba as peers
    from toolkit.api import as_scene
    from toolkit.opencl.device import get_queue
    scene = as_scene(args.scene)
    if args.peer == "embree":
        report = peers.embree_rays(scene, repeats=args.repeats, queue=get_queue(args.device))
        print(peers.format_embree(report))
    else:
        try:
            peers.load_mitsuba()
        except peers.PeerMissing as error:
            print(f"error: {error}", file=sys.stderr)
            return 2
        techniques = _technique_list(args.techniques or ",".join(peers.PEER_DEFAULT))
        report = peers.mitsuba_bench(scene, tuple(techniques), spp=args.spp, repeats=args.repeats,
                                     resolution=args.resolution, device=args.device, bvh=args.bvh)
        print(peers.format_mitsuba(report))
    if args.json:
        print(json.dumps(report))
    return 0


def cmd_crosscheck(args):
    from toolkit.api import as_scene
    from toolkit.verify.crosscheck import compare_with_embree, format_figures
    from toolkit.opencl.device import get_queue
    from toolkit.core.validate import whole_number
    whole_number("seed", args.seed, "--seed")
    whole_number("crosscheck.rays", args.rays, "--rays")
    figures = compare_with_embree(as_scene(args.scene), n_random=args.rays, seed=args.seed,
                                  queue=get_queue(args.device), bvh=args.bvh)
    print(format_figures(figures))
    if args.json:
        print(json.dumps(figures, default=lambda x: x.item() if hasattr(x, "item") else str(x)))
    return 0 if figures.get("unexplained", 0) == 0 else 1


def cmd_gpucheck(args):
    from toolkit.verify import gpucheck
    out = gpucheck.report_path(args.out)      # before the run: a bad --out must not cost its time
    report = gpucheck.run(device=args.device, fast=args.fast, out_dir=str(out.parent / (out.stem + "_compare")))
    text, data = gpucheck.write_report(report, out)
    print(gpucheck.format_report(report))
    print(f"wrote {text} and {data}")
    return 0 if report["passed"] else 1


def _numbers(text, kind, option):
    try:
        values = [kind(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"{option} must be comma-separated numbers, got {text!r}") from None
    if not values:
        raise ValueError(f"{option}: no value given")
    return values


def cmd_study(args):
    from toolkit.measure.study import format_study, study
    spp_budgets = _numbers(args.spp_budgets, int, "--spp-budgets") if args.spp_budgets else None
    budgets = _numbers(args.budgets, float, "--budgets")
    report = study(args.scene, _technique_list(args.techniques), budgets=budgets, repeats=args.repeats,
                   resolution=args.resolution, seed=args.seed, spp_budgets=spp_budgets, knob=args.knob,
                   target=args.target, scheduler=args.scheduler, device=args.device, bvh=args.bvh,
                   out_dir=args.out, progress=not args.no_progress, specialization=args.specialization)
    print(format_study(report))
    print(f"report: {args.out}/study.json")
    if args.json:
        print(json.dumps(report, default=str))
    return 0


def devices_report():
    """Text for `python -m toolkit devices`."""
    found = candidates()
    if not found:
        return HOW_TO_GET_OPENCL
    lines = ["OpenCL devices, best first (select with --device P:D or PYOPENCL_CTX=P:D):"]
    for c in found:
        state = "usable" if c.usable else f"NOT usable: {c.reason}"
        lines.append(f"  {c.selector}  {c.device.name.strip()}  [{state}]")
        lines.append(f"       implementation: {c.implementation}, compiler: {c.compiler}")
        lines.append(f"       platform: {c.platform.name.strip()} {c.platform.version.strip()}")
        lines.append(f"       type: {cl.device_type.to_string(c.device.type)}, compute units: "
                     f"{c.device.max_compute_units}, max work-group: {c.device.max_work_group_size}, "
                     f"global memory: {c.device.global_mem_size / 2**30:.1f} GiB")
        width, why = device_warp_width(c.device)
        lines.append(f"       SIMD counters: warps of {width} ({why}; --warp-width overrides)")
        lines.append(f"       in flight: {device_work_sizes(c.device).text()}; options stream_size / pool_size override")
    lines.append("Ranking of usable devices: " + " > ".join(RANKING))
    try:
        _, device = pick_device()
        lines.append(f"The toolkit would pick: {describe(device)}")
    except NoOpenCLError as error:
        lines.append(f"The toolkit cannot pick a device: {error}")
    for variable in ("PYOPENCL_CTX", "TOOLKIT_HIDE_PLATFORMS"):
        if os.environ.get(variable):
            lines.append(f"({variable}={os.environ[variable]} is set)")
    if runtimes.registered_vendors:
        lines.append(f"Intel's CPU runtime from pip is registered beside the system's drivers "
                     f"(OCL_ICD_VENDORS={runtimes.registered_vendors}).")
    elif os.environ.get("OCL_ICD_VENDORS"):
        lines.append(f"(OCL_ICD_VENDORS={os.environ['OCL_ICD_VENDORS']} is set: the toolkit registers no runtime)")
    if not has_gpu():
        lines.append("No GPU found: kernels run on the CPU, where idle SIMD lanes cost less than "
                     "on a GPU; the SIMD-efficiency counters still model a GPU warp (of 32).")
    return "\n".join(lines)
