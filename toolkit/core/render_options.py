"""The settings of one render, in one object: `toolkit.render(scene, technique, options)` takes a
RenderOptions, and the command line (toolkit/cli/options.py: render_options) and the notebooks
build the same one. Each field is described once, here, beside its default; a bad value is an
InputError that names the field, raised when the object is made, before any work starts.

    options = RenderOptions(spp=64, seed=1, resolution=(64, 64))
    toolkit.render(scene, "pt_naive", options)
    toolkit.render(scene, "pt_naive", replace(options, bvh="binary"))   # dataclasses.replace
"""
import numbers
from dataclasses import dataclass, field, fields, replace

import numpy as np

from toolkit.core.config import checked_lanes
from toolkit.core.layout import BVH_KINDS, LOCAL_SIZE
from toolkit.core.validate import InputError, local_size, whole_number

WARP_WIDTHS = (1, 2, 4, 8, 16, 32, 64, 128)
SWITCHES = ("count_simd", "progress", "general", "time_phases")   # the fields that are True or False


@dataclass(frozen=True)
class RenderOptions:
    """The settings of one render (toolkit.render): make one with the fields you change, and
    `dataclasses.replace` it for another render. Each field is checked when the object is made."""

    #: Samples per pixel.
    spp: int = 16
    #: The seed of the random numbers: the same seed (and options) gives the same image.
    seed: int = 0
    #: (width, height) in pixels, keeping the scene's camera and field of view; None: the camera's own.
    resolution: tuple = None
    #: The OpenCL device: "P:D" indices or a part of its name; None: PYOPENCL_CTX, else the probe's pick.
    device: str = None
    #: W of the SIMD-efficiency counters; None: the device's (toolkit.opencl.device_model.choose_warp_width:
    #: 32 on NVIDIA and on a CPU, 64 on AMD, 16 on Intel GPUs); stats["warp_width_source"] says which.
    warp_width: int = None
    #: Count active and issued lanes per phase (stats["simd_efficiency"]); off, the kernels run a little faster.
    count_simd: bool = True
    #: A progress bar (tqdm) on stderr.
    progress: bool = False
    #: "wide": 8 children per node tested together with float8 operations (4 with float4 where work-items
    #: run as SIMD lanes): SIMD inside one ray; "binary": the SAH BVH it is collapsed from. The same image.
    bvh: str = "wide"
    #: The work-group size the kernels are built and launched with, a power of two 32 .. 256; random numbers
    #: are keyed by sample, not by work-item, so the image does not depend on it (tests/test_strategies.py).
    local_size: int = LOCAL_SIZE
    #: True: the general kernel (every material and feature compiled in) instead of the one specialized to
    #: the scene (Scene.features; toolkit/measure/specialization.py measures what that costs). The same image.
    general: bool = False
    #: K (bdpt_* only): also keep one image per connection strategy (s, t) of the paths up to K edges, with
    #: and without its MIS weight, in result.strategy_images (toolkit/measure/strategies.py). The same image.
    strategy_images: int = None
    #: "on" or "off": whether the compiler may run work-items as SIMD lanes, on Intel's CPU runtime
    #: (toolkit/opencl/lanes.py); None: TOOLKIT_LANES, else off. stats["lanes"] says what the device did.
    lanes: str = None
    #: True: a profiling queue; each kernel's launches and device seconds in stats["kernel_times"], the
    #: lane-steps behind the SIMD efficiencies in stats["simd_lane_steps"] (toolkit/measure/phases.py).
    time_phases: bool = False
    #: The technique's own options, {name: value}: the keyword parameters of its constructor
    #: (toolkit.api.technique_options lists them; docs/techniques/ has a table per technique).
    technique_options: dict = field(default_factory=dict)

    def __post_init__(self):
        # Frozen: the checked (and normalised) values are set once, here.
        for name, value in checked_fields(self).items():
            object.__setattr__(self, name, value)


def checked_fields(options):
    """Each field of `options` checked: {name: its value as render uses it}; else an InputError
    that names the field."""
    o = options
    if o.resolution is not None and (isinstance(o.resolution, (str, bytes)) or not hasattr(o.resolution, "__len__")
                                     or len(o.resolution) != 2):
        raise InputError(f"resolution must be (width, height), got {o.resolution!r}")
    if o.device is not None and not isinstance(o.device, str):
        raise InputError(f"device must be a string like '0:0' or a name part, got {o.device!r}")
    if o.warp_width is not None and o.warp_width not in WARP_WIDTHS:
        raise InputError(f"warp_width must be a power of two up to 128, got {o.warp_width!r}")
    if o.bvh not in BVH_KINDS:
        raise InputError(f"bvh must be one of {', '.join(BVH_KINDS)}, got {o.bvh!r}")
    checked_lanes(o.lanes)
    if not isinstance(o.technique_options, dict):
        raise InputError(f"technique_options must be a dict, got {type(o.technique_options).__name__}")
    for name in SWITCHES:
        value = getattr(o, name)
        if not (isinstance(value, (bool, np.bool_)) or (isinstance(value, numbers.Integral) and value in (0, 1))):
            raise InputError(f"{name} must be True or False, got {value!r}")
    return {"spp": whole_number("spp", o.spp), "seed": whole_number("seed", o.seed),
            "resolution": o.resolution if o.resolution is None else (
                whole_number("camera.width", o.resolution[0], "resolution width"),
                whole_number("camera.height", o.resolution[1], "resolution height")),
            "local_size": local_size(o.local_size),
            "strategy_images": (None if o.strategy_images is None else
                                whole_number("render.strategy_images", o.strategy_images, "strategy_images")),
            "technique_options": dict(o.technique_options),    # a copy: the caller's dict may change later
            **{name: bool(getattr(o, name)) for name in SWITCHES}}


FIELDS = tuple(f.name for f in fields(RenderOptions))


def with_fields(options=None, **changes):
    """`options` (a RenderOptions; None: the defaults) with `changes`, each a field: a new
    RenderOptions, checked. A name that is no field is a TypeError that lists the fields."""
    unknown = sorted(set(changes) - set(FIELDS))
    if unknown:
        raise TypeError(f"no render option {', '.join(map(repr, unknown))} (the options: {', '.join(FIELDS)})")
    if options is None:
        return RenderOptions(**changes)
    if not isinstance(options, RenderOptions):
        raise InputError(f"options must be a RenderOptions, got {type(options).__name__}")
    return replace(options, **changes)
