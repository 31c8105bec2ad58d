"""`python -m toolkit bench`: samples/s of each technique and their ratios, measured in one run;
or instead, with one option each: equal-time errors (--equal-time), the kernels specialized to the
scene against the general one (--specialization), or a peer renderer beside ours (--peer)."""
import json
import sys

from toolkit.api import as_scene
from toolkit.cli.options import (BVH, DEVICE, GENERAL, LANES_BOTH, SCENE, TECHNIQUE_NAMES, number, positive,
                                 render_options, resolution, technique_list)
from toolkit.core.validate import finite_number, whole_number
from toolkit.measure import specialization
from toolkit.measure.bench import DEFAULT, bench, format_bench
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
    p.add_argument("--repeats", type=positive, default=3)
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
    p.add_argument("--json", action="store_true")
    p.set_defaults(run=cmd_bench)


def cmd_bench(args):
    whole_number("bench.repeats", args.repeats, "--repeats")
    if args.lanes and (args.peer or args.specialization or args.equal_time is not None):
        raise ValueError("--lanes applies to the samples/s bench only, not to --peer, --specialization or "
                         "--equal-time")
    if args.peer:
        return cmd_bench_peer(args)
    if args.specialization:
        return cmd_bench_specialization(args)
    if args.equal_time is not None:
        return cmd_bench_equal_time(args)
    # --lanes here is a list of settings, each a row of the bench: not one render's.
    report = bench(args.scene, tuple(technique_list(args.techniques or ",".join(DEFAULT))),
                   render_options(args, lanes=None), repeats=args.repeats, lanes=args.lanes or (None,))
    print(format_bench(report))
    if args.json:
        print(json.dumps(report))
    return 0


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
        args.scene, techniques, resolution=args.resolution or (64, 64), spp=args.spp, repeats=args.repeats,
        device=args.device, bvh=args.bvh, progress=lambda line: print(line, file=sys.stderr, flush=True))
    print(specialization.format_specialization(report))
    if args.json:
        print(json.dumps(report))
    return 0


def cmd_bench_peer(args):
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
        techniques = technique_list(args.techniques or ",".join(peers.PEER_DEFAULT))
        report = peers.mitsuba_bench(scene, tuple(techniques), spp=args.spp, repeats=args.repeats,
                                     resolution=args.resolution, device=args.device, bvh=args.bvh,
                                     reference_at=reference_at)
        print(peers.format_mitsuba(report))
    if args.json:
        print(json.dumps(report))
    return 0

