"""`toolkit.render(...)`: the one entry point that the CLI, compare, bench and tests share."""
import contextlib
import inspect
import sys
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolkit.opencl.kernel_times import KernelTimes, profiling_queue
from toolkit.opencl.device import describe, get_queue
from toolkit.opencl.lanes import describe as describe_lanes
from toolkit.opencl.lanes import width as lane_width
from toolkit.opencl.device_scene import DeviceScene, build_ahead
from toolkit.core.scene import Scene, bundled_scene_dir, check_scene, load_scene
from toolkit.techniques import get_technique
from toolkit.techniques.strategy_images import StrategyImages
from toolkit.core.render_options import RenderOptions, with_fields
from toolkit.core.validate import InputError, camera_size


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
    # per-iteration SIMD figures, for plots: a sequence of dicts (toolkit/core/simd.py StepFigures)
    iterations: Sequence = field(default_factory=list)
    strategy_images: StrategyImages = None   # per-strategy images (RenderOptions.strategy_images=K), else None


def as_scene(scene):
    if isinstance(scene, Scene):
        check_scene(scene)      # made in Python: the same limits as a loaded scene
        return scene
    if not isinstance(scene, (str, Path)) and scene is not None:
        raise InputError(f"scene must be a Scene, a folder or a scene.json path, got {type(scene).__name__}")
    return load_scene(bundled_scene_dir() if scene is None else scene)


# Constructor keywords that render sets from RenderOptions' own fields: not technique options.
RENDER_ARGUMENTS = {"warp_width", "count_simd", "extra_defines", "local_size", "general",
                    "strategy_max_edges"}   # the last: RenderOptions.strategy_images=K


def technique_options(cls):
    """The options `render` passes (RenderOptions.technique_options) to technique class `cls`: {name:
    (default, the class whose constructor takes it)}, the most specific constructor first. The keyword
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
    known = technique_options(cls)
    for key in options:
        if key not in known:
            raise InputError(f"unknown option {key!r} for {cls.name} (known: {', '.join(sorted(known)) or 'none'})")
    return options


def _strategy_images(cls, technique, max_edges):
    """render's `strategy_images` (checked by RenderOptions), for this technique: None or the longest
    paths (edges) with images of their own."""
    if max_edges is not None and cls.family != "bdpt":
        raise InputError(f"per-strategy images need a bidirectional technique (bdpt_naive_connect or "
                         f"bdpt_parallel_connect), not {technique}")
    return max_edges


def render(scene=None, technique="pt_naive", options=None, **fields):
    """Render `scene` (a Scene, a folder, a scene.json, or None for the bundled Cornell box) with
    `technique` (a name from toolkit.techniques.TECHNIQUES, or a variant such as
    "pt_compact_regen/multipass") and `options`, a RenderOptions: every field is described once in
    toolkit/core/render_options.py. Fields may also be given as keywords (`render(scene, spp=64)`),
    alone or on top of an options object; a dict as `options` is the technique's own options (its
    technique_options field). Returns a RenderResult: the image, its standard error and the stats.
    """
    # Every argument is checked before any work (kernel builds, BVH) starts.
    options = _render_options(options, fields)
    cls, tech_options, strategy_max_edges = _checked(technique, options)
    scene = as_scene(scene)
    width, height = camera_size(*(options.resolution or (scene.camera.width, scene.camera.height)), options.spp)
    build_ahead(scene)          # a big scene's BVH before the OpenCL context: not both in memory at once
    queue = get_queue(options.device, options.lanes)
    if options.time_phases:
        queue = profiling_queue(queue)
    builds = len(queue.builds.lanes_log)   # the programs this render builds (or finds built) follow
    device_scene = DeviceScene(queue, scene, bvh=options.bvh)
    tech = cls(queue, device_scene, warp_width=options.warp_width, count_simd=options.count_simd,
               local_size=options.local_size, general=options.general, **tech_options,
               **({"strategy_max_edges": strategy_max_edges} if strategy_max_edges else {}))
    times = KernelTimes(queue) if options.time_phases else None
    with times or _nothing():
        film, seconds = _run(tech, f"{technique} {scene.name} {width}x{height}", width, height, options.spp,
                             options.seed, options.progress)
    image, stderr = film.image(), film.stderr()
    stats = {"scene": scene.name, "technique": technique, "spp": options.spp, "resolution": [width, height],
             **_stats(tech, film, image, seconds), "bvh": device_scene.bvh_stats(),
             "triangles": int(len(scene.triangles)), "degrees_of_freedom": film.degrees_of_freedom,
             **_lanes_stats(queue, queue.builds.vector_widths_since(builds)), **tech.extra_stats(),
             **(_phase_stats(tech, times) if times else {})}
    if film.nonfinite_samples:
        # A non-finite sample is a bug to fix where it comes from; never only inside the stats.
        warnings.warn(f"{technique} on {scene.name}: {film.nonfinite_samples} non-finite sample(s) "
                      "were dropped from the image", DroppedSamplesWarning, stacklevel=2)
    return RenderResult(image, stderr, stats, tech.recorder.simd.per_iteration if options.count_simd else [],
                        tech.strategy_images if strategy_max_edges else None)


def _render_options(options, fields):
    """render's RenderOptions: `options` with the keyword `fields` on top. A dict as `options` is
    the technique's options, as it was before RenderOptions (render(..., options={"pass_spp": 4}))."""
    if not isinstance(options, (RenderOptions, dict, type(None))):
        raise InputError(f"options must be a RenderOptions (or a dict of the technique's options), "
                         f"got {type(options).__name__}")
    if isinstance(options, dict):
        if "technique_options" in fields:
            raise InputError("technique options given twice: as options={...} and as technique_options")
        options, fields = None, {**fields, "technique_options": options}
    return with_fields(options, **fields)


def _checked(technique, options):
    """What of render's `options` (a RenderOptions) depends on the technique, checked: (the technique
    class, its options with the variant's, strategy_max_edges or None)."""
    if not isinstance(technique, str):
        raise InputError(f"technique must be a name, got {technique!r}")
    cls, variant_options = get_technique(technique)
    technique_options = _options(cls, options.technique_options)
    strategy_max_edges = _strategy_images(cls, technique, options.strategy_images)
    return cls, {**variant_options, **technique_options}, strategy_max_edges


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
            "kernel_times_reading_seconds": times.reading_seconds,   # the host's CPU time reading the events
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
