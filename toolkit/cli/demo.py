"""`python -m toolkit demo [SCENE]`: the talk's demo, live in a browser (toolkit/demo/). Everything
the command line names is checked before the server starts: a bad scene, resolution, technique or
device is one `error:` line and exit code 2."""
import argparse
import sys

from toolkit.cli.options import DEVICE, LANES_HELP, TECHNIQUE_NAMES, resolution, technique_list, whole
from toolkit.demo import DemoUnavailable, require_panel
from toolkit.demo.scenes import SceneChoices
from toolkit.demo.settings import DEFAULT_TECHNIQUES, MOST_TECHNIQUES, Settings
from toolkit.opencl.device import get_queue


def port(text):
    value = whole(text)
    if not 1 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"a port is 1 .. 65535, got {value}")
    return value


def add_command(sub):
    p = sub.add_parser("demo", parents=[DEVICE],
                       help="the talk's demo, live in a browser: techniques side by side, SIMD efficiency, "
                            "the lanes of a few warps, Metropolis's startup bias (needs pip install \".[demo]\")")
    p.add_argument("scene", nargs="?",
                   help="a scene folder (or its scene.json, or a folder of scene folders) the page may open beside "
                        "the bundled scenes, or a bundled scene's name (default cornell_box)")
    p.add_argument("--techniques", default=",".join(DEFAULT_TECHNIQUES),
                   help=f"1 to {MOST_TECHNIQUES}, comma-separated, side by side (default {','.join(DEFAULT_TECHNIQUES)}; "
                        f"from {TECHNIQUE_NAMES}; variants excepted)")
    p.add_argument("--resolution", type=resolution, default=(128, 128), help="WxH (default 128x128; at most 1024x1024)")
    p.add_argument("--lanes", choices=["on", "off"], default=None, help=LANES_HELP)
    p.add_argument("--seed", type=whole, default=0, help="0 .. 2^32 - 1, the same for every technique")
    p.add_argument("--host", default=None,
                   help="listen on this address instead of 127.0.0.1 (prints a warning: anyone who can reach it "
                        "can use the demo and the device)")
    p.add_argument("--port", type=port, default=None, help="the port (default: a free one)")
    p.add_argument("--no-browser", action="store_true", help="print the URL without opening a browser")
    p.add_argument("--bench", action="store_true",
                   help="instead of serving: frames per second of the live view, and the samples/s it costs against "
                        "a plain render of each technique (toolkit/demo/bench.py)")
    p.add_argument("--bench-seconds", type=float, default=6.0, metavar="S",
                   help="with --bench: seconds of live view per technique and run (default 6)")
    p.set_defaults(run=cmd_demo)


def cmd_demo(args):
    try:
        require_panel()
    except DemoUnavailable as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    scenes = SceneChoices(args.scene)
    settings = Settings(techniques=tuple(technique_list(args.techniques)), scene=scenes.first,
                        resolution=args.resolution, lanes=args.lanes, seed=args.seed).changed()
    device = getattr(args, "device", None)
    get_queue(device, settings.lanes)        # a bad device or lanes setting stops here, before serving
    if args.bench:
        from toolkit.demo.bench import bench_live_view, format_live_bench
        print(format_live_bench(bench_live_view(scenes, settings, device, seconds=args.bench_seconds)))
        return 0
    from toolkit.demo.server import LOOPBACK, DemoServer
    host = args.host or LOOPBACK
    if args.host is not None:
        print(f"warning: --host {args.host}: the demo answers whoever can reach this address, and runs their "
              "choices on your device; it has no login", file=sys.stderr)
    server = DemoServer(scenes, settings, device, host=host, port=args.port)
    return server.run(open_browser=not args.no_browser)
