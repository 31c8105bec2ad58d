"""`toolkit.render(...)`: the one entry point that the CLI, compare, bench and tests share."""
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .device import describe, get_queue
from .device_scene import DeviceScene
from .scene import Scene, bundled_scene_dir, load_scene
from .techniques import get_technique


@dataclass
class RenderResult:
    image: np.ndarray      # (H, W, 3) float64 mean radiance
    stderr: np.ndarray     # (H, W, 3) per-pixel standard error of the mean
    stats: dict = field(default_factory=dict)
    iterations: list = field(default_factory=list)   # per-iteration SIMD figures, for plots


def as_scene(scene):
    if isinstance(scene, Scene):
        return scene
    return load_scene(bundled_scene_dir() if scene is None else scene)


def render(scene=None, technique="pt_naive", spp=16, seed=0, resolution=None, device=None,
           warp_width=32, count_simd=True, progress=False, options=None):
    """Render a scene (a Scene, a folder, a scene.json or None for the bundled Cornell box).

    `resolution` (width, height) keeps the scene's camera and field of view. `technique` is a
    name from toolkit.techniques.TECHNIQUES, optionally with a variant ("pt_compact_regen/multipass");
    `options` are passed to the technique. Returns a RenderResult with the image, its
    standard-error image and stats (timings, SIMD efficiency).
    """
    scene = as_scene(scene)
    width, height = resolution or (scene.camera.width, scene.camera.height)
    if warp_width not in (1, 2, 4, 8, 16, 32, 64, 128):
        raise ValueError(f"warp width must be a power of two up to 128, got {warp_width}")
    if spp < 1:
        raise ValueError("spp must be at least 1")
    queue = get_queue(device)
    device_scene = DeviceScene(queue, scene)
    cls, variant_options = get_technique(technique)
    tech = cls(queue, device_scene, warp_width=warp_width, count_simd=count_simd,
               **{**variant_options, **(options or {})})
    bar = None
    if progress:
        from tqdm.auto import tqdm
        bar = tqdm(total=spp, unit="spp", desc=f"{technique} {scene.name} {width}x{height}",
                   file=sys.stderr, leave=False)
    start = time.perf_counter()
    film = tech.render(width, height, spp, seed=seed, progress=bar)
    seconds = time.perf_counter() - start
    if bar is not None:
        bar.close()
    image, stderr = film.image(), film.stderr()
    stats = {
        "scene": scene.name,
        "technique": technique,
        "spp": spp,
        "resolution": [width, height],
        "seconds": seconds,
        "samples_per_second": film.samples / seconds if seconds > 0 else float("inf"),
        "device": describe(queue.device),
        "mean": image.reshape(-1, 3).mean(0).tolist(),
        "nonfinite": int(np.count_nonzero(~np.isfinite(image).all(-1))),
        "nonfinite_samples": film.nonfinite_samples,
        "samples_per_pixel": [int(film.count.min()), int(film.count.max())],
        "simd_efficiency": tech.simd_efficiency(),
        "traversal_efficiency": tech.traversal.efficiency() if count_simd else {},
        "build_seconds": tech.build_seconds,
        "bvh": {"nodes": device_scene.bvh.node_count, "leaves": device_scene.bvh.leaf_nodes,
                "depth": device_scene.bvh.max_depth, "build_seconds": device_scene.bvh.build_seconds},
        "triangles": int(len(scene.triangles)),
        "degrees_of_freedom": film.degrees_of_freedom,
        **tech.extra_stats(),
    }
    return RenderResult(image, stderr, stats, tech.simd.per_iteration if count_simd else [])
