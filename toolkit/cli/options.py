"""What the commands share: the types of their arguments (a bad value gets argparse's usage, the
reason and exit code 2) and the options that mean the same in every command, as argparse parents
(`sub.add_parser(..., parents=[DEVICE, BVH])`)."""
import argparse

from toolkit.core.render_options import FIELDS, RenderOptions
from toolkit.techniques import TECHNIQUES, VARIANTS, get_technique

DEVICE_HELP = "OpenCL device: P:D indices or a name part (overrides PYOPENCL_CTX)"
# What --techniques accepts, for the help of the commands that run several (compare, bench, study).
TECHNIQUE_NAMES = ", ".join([*sorted(TECHNIQUES), *VARIANTS])
KERNEL_OPTIONS = "kernel options"   # the heading of --bvh and --general in a command's --help


def resolution(text):
    try:
        w, h = (int(x) for x in text.lower().split("x"))
        if w < 1 or h < 1:
            raise ValueError
        return w, h
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT like 64x64, got {text!r}") from None


def number(text):
    """A float, checked for range later (validate.py), so the message names the limit."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def whole(text):
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None


def positive(text):
    value = whole(text)
    if value < 1:
        raise argparse.ArgumentTypeError("must be at least 1")
    return value


def technique_list(text):
    """'a,b' -> ["a", "b"], each a known technique (or variant)."""
    names = [t.strip() for t in text.split(",") if t.strip()]
    for name in names:
        get_technique(name)   # raises a clear ValueError for an unknown name
    if not names:
        raise ValueError("no technique given")
    return names


def lanes_list(text):
    """'off,on' -> ("off", "on"): SIMD-lanes settings for bench, each once."""
    settings = tuple(t.strip() for t in text.split(",") if t.strip())
    if not settings or any(s not in ("on", "off") for s in settings) or len(set(settings)) < len(settings):
        raise argparse.ArgumentTypeError(f"expected on, off or off,on, got {text!r}")
    return settings


def numbers(text, kind, option):
    """'1,2' -> [kind(1), kind(2)]; a ValueError that names `option` otherwise."""
    try:
        values = [kind(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"{option} must be comma-separated numbers, got {text!r}") from None
    if not values:
        raise ValueError(f"{option}: no value given")
    return values


def render_options(args, **fields):
    """The RenderOptions of a command's parsed arguments: the one place where the command line's
    options become render's. Each option named as a field (--spp, --seed, --resolution, --device,
    --warp-width, --bvh, --general, --lanes) is taken as it is, --no-progress turns `progress` off;
    `fields` are what the command sets itself, on top. A bad value is an InputError (exit code 2)."""
    given = {name: getattr(args, name) for name in FIELDS if hasattr(args, name)}
    if hasattr(args, "no_progress"):
        given["progress"] = not args.no_progress
    return RenderOptions(**{**given, **fields})


def _parent():
    return argparse.ArgumentParser(add_help=False)   # a parent adds its options, not a second -h


# Also accepted after the command; SUPPRESS keeps a value given before it (the main parser's --device).
DEVICE = _parent()
DEVICE.add_argument("--device", default=argparse.SUPPRESS, help=DEVICE_HELP)

BVH = _parent()
BVH.add_argument_group(KERNEL_OPTIONS).add_argument(
    "--bvh", choices=["binary", "wide"], default="wide",
    help="wide: 8 children per node tested with float8 operations (SIMD inside one ray; 4 with float4 "
         "where work-items run as SIMD lanes); "
         "binary: the SAH BVH it is collapsed from (default wide)")

GENERAL = _parent()
GENERAL.add_argument_group(KERNEL_OPTIONS).add_argument(
    "--general", action="store_true",
    help="build the general kernel (every material and feature compiled in) instead of "
         "the one specialized to the scene; the same image (bench --specialization "
         "measures the difference)")

LANES_HELP = ("on: the compiler may run work-items as the SIMD lanes of a vector register, a warp on a CPU; off: "
              "each work-item a thread of its own. Intel's CPU runtime only (its log's vector width is reported); "
              "default off, or the TOOLKIT_LANES environment variable. Both can run in one process, unless "
              "CL_CONFIG_USE_VECTORIZER=False or CL_CONFIG_CPU_VECTORIZER_MODE is set, which fixes it for the "
              "process")
LANES = _parent()
LANES.add_argument_group(KERNEL_OPTIONS).add_argument("--lanes", choices=["on", "off"], default=None,
                                                      help=LANES_HELP)
# bench's: one setting, or both in one run ("off,on", interleaved).
LANES_BOTH = _parent()
LANES_BOTH.add_argument_group(KERNEL_OPTIONS).add_argument(
    "--lanes", type=lanes_list, default=None, metavar="on|off|off,on",
    help=LANES_HELP + ". With off,on every technique runs both ways in the same run, interleaved, with its "
                      "on/off ratio")

SCENE = _parent()
SCENE.add_argument("scene", nargs="?", help="scene folder, scene.json or a bundled scene's name (default: cornell_box)")
