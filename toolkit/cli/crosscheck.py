"""`python -m toolkit crosscheck`: our BVH traversal against Embree's on the same rays."""
import json

from toolkit.api import as_scene
from toolkit.cli.options import BVH, DEVICE, SCENE, positive, whole
from toolkit.core.validate import whole_number
from toolkit.opencl.device import get_queue
from toolkit.verify.crosscheck import compare_with_embree, format_figures


def add_command(sub):
    p = sub.add_parser("crosscheck", help="our BVH traversal against Embree: agreement figures",
                       parents=[DEVICE, SCENE, BVH])
    p.add_argument("--rays", type=positive, default=100_000, help="random rays besides the camera rays")
    p.add_argument("--seed", type=whole, default=0, help="0 .. 2^32 - 1")
    p.add_argument("--json", action="store_true")
    p.set_defaults(run=cmd_crosscheck)


def cmd_crosscheck(args):
    whole_number("seed", args.seed, "--seed")
    whole_number("crosscheck.rays", args.rays, "--rays")
    figures = compare_with_embree(as_scene(args.scene), n_random=args.rays, seed=args.seed,
                                  queue=get_queue(args.device), bvh=args.bvh)
    print(format_figures(figures))
    if args.json:
        print(json.dumps(figures, default=lambda x: x.item() if hasattr(x, "item") else str(x)))
    return 0 if figures.get("unexplained", 0) == 0 else 1
