"""`toolkit.render(...)`: the one entry point that the CLI, compare, bench and tests share."""
import contextlib
import inspect
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolkit.opencl.kernel_times import KernelTimes, profiling_queue
from toolkit.opencl.device import describe, get_queue
from toolkit.opencl.lanes import checked as checked_lanes, describe as describe_lanes
from toolkit.opencl.lanes import width as lane_width
from toolkit.opencl.device_scene import DeviceScene
from toolkit.core.layout import BVH_KINDS
from toolkit.core.scene import Scene, bundled_scene_dir, check_scene, load_scene
from toolkit.techniques import get_technique
from toolkit.techniques.strategy_images import StrategyImages
from toolkit.opencl.program import LOCAL_SIZE
from toolkit.core.validate import InputError, local_size as checked_local_size, render_args, whole_number


class DroppedSamplesWarning(UserWarning):
    """Samples that came out NaN or infinite were left out of the image: a bug, reported."""


@dataclass
class RenderResult:
    """What `render` returns: the image (the mean), its per-pixel standard error, the figures of
    the run (`stats`: seconds, samples/s, SIMD efficiency, device, ...), the SIMD figures of
    each iteration, and for BDPT the per-strategy images when they were asked for."""
    image: np.ndarray      # (H, W, 3) float64 mean radiance
    stderr: np.ndarray     # (H, W, 3) per-pixel standard error of the mean
    stats: dict = field(default_factory=dict)
    iterations: list = field(default_factory=list)   # per-iteration SIMD figures, for plots
    strategy_images: StrategyImages = None   # per-strategy images (render(..., strategy_images=K)), else None


def as_scene(scene):
    if isinstance(scene, Scene):
        check_scene(scene)      # made in Python: the same limits as a loaded scene
        return scene
    if not isinstance(scene, (str, Path)) and scene is not None:
        raise InputError(f"scene must be a Scene, a folder or a scene.json path, got {type(scene).__name__}")
    return load_scene(bundled_scene_dir() if scene is None else scene)


# Constructor keywords that render sets from its own arguments: not options.
RENDER_ARGUMENTS = {"warp_width", "count_simd", "extra_defines", "local_size", "general",
                    "strategy_max_edges"}   # the last: render(..., strategy_images=K)


def technique_options(cls):
    """The options `render(..., options={...})` passes to technique class `cls`: {name: (default,
    the class whose constructor takes it)}, the most specific constructor first. The keyword
    parameters of its constructors, less render's own arguments (RENDER_ARGUMENTS)."""
    found = {}
    for c in cls.__mro__:
        if "__init__" not in vars(c):
            continue
        for name, p in inspect.signature(c.__init__).parameters.items():
            if name not in RENDER_ARGUMENTS and name not in found and (
                    p.kind == p.KEYWORD_ONLY or (p.kind == p.POSITIONAL_OR_KEYWORD and p.default is not p.empty)):
                found[name] = (p.default, c.__name__)
    return found


def _options(cls, options):
    """Technique options must be keyword parameters of the technique's constructors."""
    if not isinstance(options, dict):
        raise InputError(f"options must be a dict, got {type(options).__name__}")
    known = technique_options(cls)
    for key in options:
        if key not in known:
            raise InputError(f"unknown option {key!r} for {cls.name} (known: {', '.join(sorted(known)) or 'none'})")
    return options


def _strategy_images(cls, technique, max_edges):
    """render's `strategy_images`, checked: None or the longest paths (edges) with images of their own."""
    if max_edges is None:
        return None
    if cls.family != "bdpt":
        raise InputError(f"per-strategy images need a bidirectional technique (bdpt_naive_connect or "
                         f"bdpt_parallel_connect), not {technique}")
    return whole_number("render.strategy_images", max_edges, "strategy_images")


def render(scene=None, technique="pt_naive", spp=16, seed=0, resolution=None, device=None,
           warp_width=None, count_simd=True, progress=False, options=None, bvh="wide", local_size=LOCAL_SIZE,
           general=False, strategy_images=None, lanes=None, time_phases=False):
    """Render a scene (a Scene, a folder, a scene.json or None for the bundled Cornell box).

    `resolution` (width, height) keeps the scene's camera and field of view. `technique` is a
    name from toolkit.techniques.TECHNIQUES, optionally with a variant ("pt_compact_regen/multipass");
    `options` are passed to the technique. Returns a RenderResult with the image, its
    standard-error image and stats (timings, SIMD efficiency). `bvh` is "wide" (eight children
    per node tested together with float8 operations, four with float4 where work-items run as SIMD
    lanes: SIMD inside one ray) or "binary"; both
    give the same image (tests/test_wide_bvh.py). `local_size` is the work-group size the
    kernels are built and launched with, a power of two 32 .. 256; random numbers are keyed by
    sample, not by work-item, so the image does not depend on it (tests/test_strategies.py).
    `warp_width` is the W of the SIMD-efficiency counters; None takes the device's
    (toolkit.opencl.device_model.choose_warp_width: 32 on NVIDIA and on a CPU, 64 on AMD, 16 on Intel GPUs);
    stats["warp_width"] and ["warp_width_source"] say which. `general=True` builds the general
    kernel (every material and feature compiled in) instead of the one specialized to the scene
    (Scene.features; toolkit/measure/specialization.py measures what that costs): the same image.
    `strategy_images=K` (bdpt_* only) also keeps one image per connection strategy (s, t) of the
    paths up to K edges, with and without its MIS weight, in result.strategy_images (a
    StrategyImages; toolkit/measure/strategies.py writes them and each strategy's share of the
    variance); the kernels are built for it, and the image stays the same.
    `lanes` "on" or "off": whether the compiler may run work-items as SIMD lanes, on Intel's CPU
    runtime (toolkit/opencl/lanes.py; None: TOOLKIT_LANES, else off); the image stays the same
    within toolkit.same_image. stats["lanes"] says what the device did, stats["vector_widths"]
    each kernel's width from the compiler's log.
    `time_phases=True` runs on a profiling queue of the same context and puts each kernel's launches
    and device seconds in stats["kernel_times"] (toolkit/opencl/kernel_times.py), with the lane-steps
    behind the SIMD efficiencies in stats["simd_lane_steps"] (toolkit/measure/phases.py reads both).
    """
    # Every argument is checked before any work (kernel builds, BVH) starts.
    cls, options, strategy_max_edges = _checked(technique, options, strategy_images, resolution, bvh, device)
    lanes = checked_lanes(lanes)
    scene = as_scene(scene)
    width, height = resolution or (scene.camera.width, scene.camera.height)
    spp, seed, width, height = render_args(spp, seed, width, height, warp_width)
    local_size = checked_local_size(local_size)
    queue = get_queue(device, lanes)
    if time_phases:
        queue = profiling_queue(queue)
    builds = len(queue.builds.lanes_log)   # the programs this render builds (or finds built) follow
    device_scene = DeviceScene(queue, scene, bvh=bvh)
    tech = cls(queue, device_scene, warp_width=warp_width, count_simd=count_simd, local_size=local_size,
               general=bool(general), **options,
               **({"strategy_max_edges": strategy_max_edges} if strategy_max_edges else {}))
    times = KernelTimes(queue) if time_phases else None
    with times or _nothing():
        film, seconds = _run(tech, f"{technique} {scene.name} {width}x{height}", width, height, spp, seed, progress)
    image, stderr = film.image(), film.stderr()
    stats = {"scene": scene.name, "technique": technique, "spp": spp, "resolution": [width, height],
             **_stats(tech, film, image, seconds), "bvh": device_scene.bvh_stats(),
             "triangles": int(len(scene.triangles)), "degrees_of_freedom": film.degrees_of_freedom,
             **_lanes_stats(queue, queue.builds.vector_widths_since(builds)), **tech.extra_stats(),
             **(_phase_stats(tech, times) if times else {})}
    if film.nonfinite_samples:
        # A non-finite sample is a bug to fix where it comes from; never only inside the stats.
        warnings.warn(f"{technique} on {scene.name}: {film.nonfinite_samples} non-finite sample(s) "
                      "were dropped from the image", DroppedSamplesWarning, stacklevel=2)
    return RenderResult(image, stderr, stats, tech.recorder.simd.per_iteration if count_simd else [],
                        tech.strategy_images if strategy_max_edges else None)


def _checked(technique, options, strategy_images, resolution, bvh, device):
    """render's arguments that need no scene, checked: (technique class, its options with the
    variant's, strategy_max_edges or None)."""
    if not isinstance(technique, str):
        raise InputError(f"technique must be a name, got {technique!r}")
    cls, variant_options = get_technique(technique)
    options = _options(cls, options if options is not None else {})
    strategy_max_edges = _strategy_images(cls, technique, strategy_images)
    if resolution is not None and (isinstance(resolution, (str, bytes)) or not hasattr(resolution, "__len__")
                                   or len(resolution) != 2):
        raise InputError(f"resolution must be (width, height), got {resolution!r}")
    if bvh not in BVH_KINDS:
        raise InputError(f"bvh must be one of {', '.join(BVH_KINDS)}, got {bvh!r}")
    if device is not None and not isinstance(device, str):
        raise InputError(f"device must be a string like '0:0' or a name part, got {device!r}")
    return cls, {**variant_options, **options}, strategy_max_edges


def _lanes_stats(queue, widths):
    """Whether the render ran work-items as SIMD lanes, and how wide, as its compiler said."""
    setting = queue.builds.lanes
    return {"lanes": setting, "vector_width": lane_width(widths), "vector_widths": widths,
            "lanes_summary": describe_lanes(setting, widths)}


def _nothing():
    return contextlib.nullcontext()


def _phase_stats(tech, times):
    """Each kernel's launches and device seconds, and the lane-steps (active, issued) of each SIMD
    counter: what a per-phase table needs beside the efficiencies."""
    def lane_steps(counter):
        return {phase: [counter.active[phase], counter.issued[phase]] for phase in counter.active}
    per_kernel = times.per_kernel()
    return {"kernel_times": {name: {"launches": n, "seconds": s} for name, (n, s) in per_kernel.items()},
            "kernel_span_seconds": times.span_seconds,
            "simd_lane_steps": lane_steps(tech.recorder.simd) if tech.count_simd else {},
            "traversal_lane_steps": lane_steps(tech.recorder.traversal) if tech.count_simd else {}}


def _run(tech, what, width, height, spp, seed, progress):
    """(the film, seconds) of tech's render, with a progress bar (named `what`) if asked."""
    bar = None
    if progress:
        from tqdm.auto import tqdm    # only with a progress bar
        bar = tqdm(total=spp, unit="spp", desc=what, file=sys.stderr, leave=False)
    start = time.perf_counter()
    film = tech.render(width, height, spp, seed=seed, progress=bar)
    seconds = time.perf_counter() - start
    if bar is not None:
        bar.close()
    return film, seconds


def _stats(tech, film, image, seconds):
    """The render's figures: speed, device, image, SIMD and traversal efficiency, the kernels."""
    count_simd = tech.count_simd
    return {
        "local_size": tech.local_size,
        "seconds": seconds,
        "samples_per_second": film.samples / seconds if seconds > 0 else float("inf"),
        "device": describe(tech.queue.device),
        "mean": image.reshape(-1, 3).mean(0).tolist(),
        "nonfinite": int(np.count_nonzero(~np.isfinite(image).all(-1))),
        "nonfinite_samples": film.nonfinite_samples,
        "samples_per_pixel": [int(film.count.min()), int(film.count.max())],
        "warp_width": tech.warp_width,
        "warp_width_source": tech.warp_width_source,
        "simd_efficiency": tech.simd_efficiency(),
        "traversal_efficiency": tech.recorder.traversal.efficiency() if count_simd else {},
        # BVH nodes (and wide leaves) visited per sample, closest-hit and shadow rays: --bvh wide cuts them.
        "traversal_steps_per_sample": ({phase: steps / film.samples for phase, steps in tech.recorder.traversal.active.items()}
                                       if count_simd and film.samples else {}),
        "build_seconds": tech.build_seconds,
        "kernels": "general" if tech.general else "specialized",
    }
