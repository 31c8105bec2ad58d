"""`python -m toolkit bench`: samples/s of each technique and their ratios, measured in one run;
or instead, with one option each: equal-time errors (--equal-time), the kernels specialized to the
scene against the general one (--specialization), or a peer renderer beside ours (--peer), or what the host spends per sample (--host)."""
import json
import sys

from toolkit.api import as_scene
from toolkit.cli.options import (BVH, DEVICE, GENERAL, LANES_BOTH, SCENE, TECHNIQUE_NAMES, number, positive,
                                 render_options, resolution, technique_list)
from toolkit.core.validate import finite_number, whole_number
from toolkit.core.errors import InputError
from toolkit.measure import gpu_model, specialization
from toolkit.measure.bench import DEFAULT, bench, format_bench
from toolkit.measure.host_meter import HOST_DEFAULT, format_host_meter, host_meter
from toolkit.measure.reference import reference_at
from toolkit.measure.study import equal_time, format_equal_time
from toolkit.opencl.device import get_queue
from toolkit.peers import mitsuba as peers


def add_command(sub):
    p = sub.add_parser("bench", help="samples/s of each technique and their ratios, measured in one run",
                       parents=[DEVICE, SCENE, BVH, GENERAL, LANES_BOTH])
    p.add_argument("--techniques", help=f"comma-separated, from: {TECHNIQUE_NAMES} (default {','.join(DEFAULT)}; "
                                        f"with --peer mitsuba: {','.join(peers.PEER_DEFAULT)})")
    p.add_argument("--spp", type=positive, default=16, help="samples per pixel for path tracers (BDPT: an eighth)")
    p.add_argument("--resolution", type=resolution, default=None,
                   help="WxH (default 128x128; with --equal-time 32x32, which every bundled reference averages to; "
                        "with --peer: the scene's own)")
    p.add_argument("--repeats", type=positive, default=None,
                   help="runs of each row (default 3); with --host: pairs of renders per technique, each figure "
                        "their median (default 1; 3 with --gpu-sizes)")
    p.add_argument("--peer", choices=["embree", "mitsuba"],
                   help="instead: embree: closest-hit rays/s of our BVHs against embreex on the same rays; "
                        "mitsuba: Mitsuba 3's path integrator beside the toolkit (spp/s, variance per sample, "
                        "time to 5%% RMSE); needs pip install \".[peers]\"")
    p.add_argument("--equal-time", type=number, metavar="SECONDS",
                   help="instead: render each technique for about SECONDS and compare RMSE against the reference")
    p.add_argument("--specialization", action="store_true",
                   help="instead: the kernels specialized to the scene against the general kernel, on SCENE or "
                        "every bundled scene: samples/s, uncached build time, binary size (default techniques "
                        "pt_naive,pt_compact_regen,bdpt_parallel_connect; resolution 64x64)")
    p.add_argument("--host", action="store_true",
                   help="instead: the host meter: each technique rendered at N and 4N samples per pixel (N: --spp "
                        "for path tracers, a quarter of it for BDPT and mlt, but --spp for all with --gpu-sizes), and what the 3N more samples cost the "
                        "host: CPU time, bytes read back and written, blocking reads, launches, the kernels' share "
                        f"(default techniques {','.join(HOST_DEFAULT)}; resolution 256x256)")
    p.add_argument("--gpu-sizes", action="store_true",
                   help="with --host: render at a GPU's stream, pool and chain sizes (the H200's), whatever the device")
    p.add_argument("--count-simd", action="store_true", dest="host_count_simd",
                   help="with --host: the renders count SIMD efficiency (as compare's, gpucheck's phases and the "
                        "demo's do): what the counters cost the host")
    p.add_argument("--predict-gpu", metavar="GPUCHECK_JSON",
                   help="instead: the model of a GPU's wall time (toolkit/measure/gpu_model.py) from the kernel times "
                        "in a gpucheck report of that GPU and the host meter's figures (--meter, else measured now "
                        "at the GPU's sizes): each technique's time per sample, samples/s against this CPU's, "
                        "the talk's two ratios")
    p.add_argument("--meter", metavar="JSON", help="with --predict-gpu: a host meter report (bench --host --gpu-sizes "
                                                   "--json's last line) instead of measuring one")
    p.add_argument("--cpu-meter", metavar="JSON", help="with --predict-gpu: a host meter report at the CPU's own sizes, "
                                                       "for this CPU's samples/s (default: --meter's)")
    p.add_argument("--host-speed", type=number, default=1.0, metavar="FACTOR",
                   help="with --predict-gpu: the GPU machine's host time over this one's for the same work "
                        "(default 1; 0.5: a host twice as fast)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(run=cmd_bench)


def cmd_bench(args):
    if args.repeats is not None:
        whole_number("bench.repeats", args.repeats, "--repeats")
    if args.lanes and (args.peer or args.specialization or args.equal_time is not None or args.host):
        raise ValueError("--lanes applies to the samples/s bench only, not to --peer, --specialization, "
                         "--equal-time or --host")
    if args.gpu_sizes and not args.host:
        raise ValueError("--gpu-sizes applies to the host meter only (--host)")
    if args.host_count_simd and not args.host:
        raise ValueError("--count-simd applies to the host meter only (--host)")
    if (args.meter or args.cpu_meter or args.host_speed != 1.0) and not args.predict_gpu:
        raise ValueError("--meter, --cpu-meter and --host-speed go with --predict-gpu")
    if args.predict_gpu:
        return cmd_bench_predict(args)
    if args.host:
        return cmd_bench_host(args)
    if args.peer:
        return cmd_bench_peer(args)
    if args.specialization:
        return cmd_bench_specialization(args)
    if args.equal_time is not None:
        return cmd_bench_equal_time(args)
    # --lanes here is a list of settings, each a row of the bench: not one render's.
    report = bench(args.scene, tuple(technique_list(args.techniques or ",".join(DEFAULT))),
                   render_options(args, lanes=None), repeats=args.repeats or 3, lanes=args.lanes or (None,))
    print(format_bench(report))
    if args.json:
        print(json.dumps(report))
    return 0


def cmd_bench_host(args):
    if args.peer or args.specialization or args.equal_time is not None:
        raise ValueError("--host is a bench of its own: not with --peer, --specialization or --equal-time")
    report = host_meter(args.scene, tuple(technique_list(args.techniques or ",".join(HOST_DEFAULT))),
                        render_options(args, lanes=None), spp=args.spp, gpu_sizes=args.gpu_sizes,
                        count_simd=args.host_count_simd, repeats=args.repeats)
    print(format_host_meter(report))
    if args.json:
        print(json.dumps(report))
    return 0


def cmd_bench_predict(args):
    if args.host or args.peer or args.specialization or args.equal_time is not None:
        raise ValueError("--predict-gpu is a bench of its own: not with --host, --peer, --specialization or "
                         "--equal-time")
    gpucheck = read_report(args.predict_gpu, "--predict-gpu")
    if "phases" not in gpucheck or "device" not in gpucheck:
        raise InputError(f"--predict-gpu: {args.predict_gpu} is not a gpucheck report with its time per phase")
    if args.meter:
        meter = read_report(args.meter, "--meter")
    else:
        meter = host_meter(args.scene, tuple(technique_list(args.techniques or ",".join(HOST_DEFAULT))),
                           render_options(args, lanes=None), spp=args.spp, gpu_sizes=True)
    cpu_meter = read_report(args.cpu_meter, "--cpu-meter") if args.cpu_meter else None
    for report, option in ((meter, "--meter"), (cpu_meter, "--cpu-meter")):
        if report is not None and "techniques" not in report:
            raise InputError(f"{option}: not a host meter report (bench --host --json's last line)")
    if not 0 < args.host_speed <= 1000:   # also refuses nan and inf
        raise InputError(f"--host-speed must be above 0 and at most 1000 (the GPU machine's host time over this "
                         f"one's), got {args.host_speed:g}")
    prediction = gpu_model.predict(meter, gpucheck, cpu_meter, host_speed=args.host_speed)
    print(f"predicted for {prediction['gpu']} (a model, not a measurement: toolkit/measure/gpu_model.py states its "
          f"assumptions), from the host meter on {prediction['cpu']}, host speed x{args.host_speed:g}; ns per sample")
    print(gpu_model.format_prediction(prediction))
    if args.json:
        print(json.dumps(prediction))
    return 0


def read_report(path, option):
    """A JSON report named on the command line (untrusted: size-limited, an InputError when unreadable)."""
    try:
        with open(path, "rb") as file:
            text = file.read(MAX_REPORT_BYTES + 1)
    except OSError as error:
        raise InputError(f"{option}: cannot read {path}: {error.strerror}") from None
    if len(text) > MAX_REPORT_BYTES:
        raise InputError(f"{option}: {path} is over {MAX_REPORT_BYTES:,} bytes, larger than any report")
    try:
        report = json.loads(text)
    except (ValueError, UnicodeDecodeError) as error:
        raise InputError(f"{option}: {path} is not JSON ({error})") from None
    if not isinstance(report, dict):
        raise InputError(f"{option}: {path} holds no report")
    return report


MAX_REPORT_BYTES = 16 << 20


def cmd_bench_equal_time(args):
    finite_number("bench.equal_time", args.equal_time, "--equal-time")
    scene = args.scene or "cornell_spheres"
    report = equal_time(scene, technique_list(args.techniques or ",".join(DEFAULT)), args.equal_time,
                        resolution=args.resolution or (32, 32), device=args.device, bvh=args.bvh)
    print(format_equal_time(report, args.equal_time))
    if args.json:
        print(json.dumps(report))
    return 0


def cmd_bench_specialization(args):
    techniques = technique_list(args.techniques or ",".join(specialization.DEFAULT_TECHNIQUES))
    report = specialization.measure_specialization(
        args.scene, techniques, resolution=args.resolution or (64, 64), spp=args.spp, repeats=args.repeats or 3,
        device=args.device, bvh=args.bvh, progress=lambda line: print(line, file=sys.stderr, flush=True))
    print(specialization.format_specialization(report))
    if args.json:
        print(json.dumps(report))
    return 0


def cmd_bench_peer(args):
    scene = as_scene(args.scene)
    if args.peer == "embree":
        report = peers.embree_rays(scene, repeats=args.repeats or 3, queue=get_queue(args.device))
        print(peers.format_embree(report))
    else:
        try:
            peers.load_mitsuba()
        except peers.PeerMissing as error:
            print(f"error: {error}", file=sys.stderr)
            return 2
        techniques = technique_list(args.techniques or ",".join(peers.PEER_DEFAULT))
        report = peers.mitsuba_bench(scene, tuple(techniques), spp=args.spp, repeats=args.repeats or 3,
                                     resolution=args.resolution, device=args.device, bvh=args.bvh,
                                     reference_at=reference_at)
        print(peers.format_mitsuba(report))
    if args.json:
        print(json.dumps(report))
    return 0

