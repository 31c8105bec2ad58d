"""`python -m toolkit render`: one technique on one scene, an image and a summary; with
--strategies (bdpt_* only), an image per connection strategy instead."""
import json

import numpy as np

from toolkit.api import as_scene, render
from toolkit.cli.options import BVH, DEVICE, GENERAL, LANES, SCENE, positive, render_options, resolution, whole
from toolkit.core.images import write_image
from toolkit.core.validate import check_output
from toolkit.measure.reference import reference_at, reference_problem, rmse
from toolkit.measure.strategies import check_strategies_folder, format_strategies, write_strategies
from toolkit.techniques import TECHNIQUES
from toolkit.techniques.strategy_images import DEFAULT_MAX_EDGES


def add_command(sub):
    p = sub.add_parser("render", help="render a scene with one technique",
                       parents=[DEVICE, SCENE, BVH, GENERAL, LANES])
    p.add_argument("--technique", default="pt_naive", choices=sorted(TECHNIQUES))
    p.add_argument("--spp", type=positive, default=64, help="samples per pixel (default 64)")
    p.add_argument("--resolution", type=resolution, help="WxH; keeps the scene's camera and field of view")
    p.add_argument("--seed", type=whole, default=0, help="0 .. 2^32 - 1")
    p.add_argument("--out", help="output .exr (an sRGB .png is written beside it) or .png alone; default out/<scene>_<technique>.exr")
    p.add_argument("--json", action="store_true", help="print a JSON summary as the last line of stdout")
    p.add_argument("--no-progress", action="store_true")
    p.add_argument("--strategies", metavar="DIR",
                   help="bdpt_* only, instead of one image: an image per connection strategy (s, t), with and "
                        "without its MIS weight (Veach's figure 10.3), into DIR with strategies.json and a table "
                        "of each strategy's share of the image and of the variance")
    p.add_argument("--strategy-edges", type=positive, default=DEFAULT_MAX_EDGES, metavar="K",
                   help="with --strategies: strategies of paths up to K edges get images, longer paths one "
                        "summed image (default 5)")
    p.set_defaults(run=cmd_render)


def cmd_render(args):
    if args.strategies:
        return cmd_render_strategies(args)
    options = render_options(args)  # before the render: a bad value must not cost its time
    if args.out:
        check_output(args.out)      # so must a bad --out
    scene = as_scene(args.scene)
    width, height = options.resolution or (scene.camera.width, scene.camera.height)
    out = check_output(args.out or f"out/{scene.name}_{args.technique}.exr")
    result = render(scene, args.technique, options, resolution=(width, height))
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
             f"  {stats['lanes_summary']}",
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
    if args.general:
        raise ValueError("--strategies builds its own kernels; --general does not apply")
    scene = as_scene(args.scene)
    check_strategies_folder(args.strategies)     # before the render: a bad folder must not cost its time
    result = render(scene, args.technique,
                    render_options(args, count_simd=False, strategy_images=args.strategy_edges))
    report = write_strategies(args.strategies, result.image, result.strategy_images, scene.name, args.technique)
    print(format_strategies(report))
    print(f"  wrote {len(report['strategies'])} x 2 strategy images, longer_weighted.exr, full.exr and "
          f"strategies.json to {args.strategies}")
    if args.json:
        print(json.dumps(report))
    return 0
