"""`python -m toolkit compare`: several techniques side by side (time, SIMD efficiency, error),
with images and plots."""
import json

from toolkit.cli.options import (BVH, DEVICE, GENERAL, LANES, SCENE, TECHNIQUE_NAMES, positive, render_options,
                                 resolution, technique_list, whole)
from toolkit.measure.compare import compare, format_table


def add_command(sub):
    p = sub.add_parser("compare", help="several techniques side by side: time, SIMD efficiency, error",
                       parents=[DEVICE, SCENE, BVH, GENERAL, LANES])
    p.add_argument("--techniques", default="pt_naive,pt_inplace_regen,pt_compact_regen",
                   help=f"comma-separated, from: {TECHNIQUE_NAMES}")
    # 64x64 at 64 spp: a pass of 262,144 samples, eight per slot of the stream techniques'
    # 32,768, so their pools regenerate (at 8 spp each slot would hold one sample and
    # pt_inplace_regen would look like pt_naive); tutorial 2 uses the same budget.
    p.add_argument("--spp", type=positive, default=64, help="samples per pixel (default 64)")
    p.add_argument("--resolution", type=resolution, default=(64, 64), help="WxH (default 64x64)")
    p.add_argument("--seed", type=whole, default=0, help="0 .. 2^32 - 1")
    p.add_argument("--warp-width", type=int, default=None, choices=[8, 16, 32, 64],
                   help="W of the SIMD-efficiency counters (default: the device's: 32 on NVIDIA and on a CPU, "
                        "64 on AMD, 16 on Intel GPUs; `devices` shows it)")
    p.add_argument("--json", action="store_true", help="print a JSON object as the last line of stdout")
    p.add_argument("--out", default="out/compare", help="folder for images and plots (default out/compare)")
    p.add_argument("--plot", default=None, metavar="PNG",
                   help="where the figure of time per phase, lane efficiency and the talk's model goes "
                        "(default <out>/<scene>_phases.png)")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(run=cmd_compare)


def cmd_compare(args):
    table = compare(args.scene, technique_list(args.techniques), options=render_options(args), out_dir=args.out,
                    phase_plot=args.plot)
    print(format_table(table))
    first = next(iter(table.values()))
    print("plots: " + ", ".join(first.get("plots", {}).values()))
    if args.json:
        print(json.dumps(table))
    return 0
