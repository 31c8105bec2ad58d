"""What "model only what a scene requires" buys, measured (`python -m toolkit bench --specialization`).

The toolkit builds each kernel for its scene: only the materials the scene uses, no depth-limit
or roulette test it does not need (Scene.features). The general kernel (`general=True`) has
every material and feature compiled in, as a renderer that does not specialize would ship it.
Both compute the same image (tests/test_specialization.py); this module measures, per scene
and technique, what each costs on this device:

- samples/s: the median of `repeats` renders, interleaved (specialized, general, specialized,
  ...) so that a slow moment of the machine favours neither; build and warm-up excluded;
- build seconds, uncached: pyopencl keeps built binaries on disk and PoCL its compiled kernels,
  keyed by the source and the options. Each build here is made past pyopencl's binary cache
  (the technique's `binary_cache=False`: neither looked up nor stored, so the user's cache is not
  filled) and gets a define no source reads (-DUNCACHED_BUILD=<nonce>), which changes PoCL's key
  and nothing else;
- warm-up seconds: the first render after the build, of the timed size. PoCL compiles each
  kernel's work-group function at its first launch, so on a CPU part of the compile cost lands
  here (and the first render of a size allocates its buffers);
- binary bytes: the program binary's size (CL_PROGRAM_BINARY_SIZES): LLVM bitcode on PoCL,
  device code on most GPU drivers.
"""
import statistics
import time
import uuid
from pathlib import Path

import pyopencl as cl

from toolkit.api import as_scene
from toolkit.opencl.device import describe, get_queue
from toolkit.opencl.device_scene import DeviceScene
from toolkit.core.scene import Scene, bundled_scene_dir
from toolkit.techniques import get_technique

DEFAULT_TECHNIQUES = ("pt_naive", "pt_compact_regen", "bdpt_parallel_connect")
KERNELS = ("specialized", "general")


def bundled_scenes():
    """The folders of every scene shipped with the toolkit."""
    root = bundled_scene_dir().parent
    return sorted(p for p in root.iterdir() if (p / "scene.json").is_file())


def _build(queue, device_scene, technique, general):
    """The technique built uncached (see the module's docstring), and its build's figures."""
    cls, options = get_technique(technique)
    tech = cls(queue, device_scene, count_simd=False, general=general, binary_cache=False,
               extra_defines={"UNCACHED_BUILD": uuid.uuid4().int % 10**12}, **options)
    sizes = tech.kernels.program.get_info(cl.program_info.BINARY_SIZES)
    return tech, {"build_seconds": tech.build_seconds, "binary_bytes": int(sum(sizes))}


def _samples_per_second(tech, width, height, spp, seed):
    start = time.perf_counter()
    film = tech.render(width, height, spp, seed=seed)
    return film.samples / (time.perf_counter() - start)


def measure_specialization(scenes=None, techniques=DEFAULT_TECHNIQUES, resolution=(64, 64), spp=8,
                           repeats=3, device=None, bvh="wide", progress=None):
    """Specialized against general kernels, per scene and technique.

    `scenes`: a scene (a Scene or a folder), a list of them, or None for every bundled scene. `spp` is for the
    path tracers; bidirectional techniques (and mlt) get an eighth, as in `bench`, since a
    sample of theirs costs ~10x more. `progress`: None, or a function called with a line of
    text before each measurement. Returns
    {"device", "resolution", "spp", "repeats", "scenes": {scene: {technique: {
        "specialized": {...}, "general": {...}, "speedup"}}}}
    where each kernel's entry holds samples_per_second (median), runs, build_seconds,
    warmup_seconds and binary_bytes, and speedup is specialized / general samples/s.
    """
    if scenes is None:
        scenes = bundled_scenes()
    elif isinstance(scenes, (str, Path, Scene)):
        scenes = [scenes]
    queue = get_queue(device)
    width, height = resolution
    report = {"device": describe(queue.device), "resolution": [width, height], "spp": spp,
              "repeats": repeats, "bvh": bvh, "scenes": {}}
    for given in scenes:
        scene = as_scene(given)
        device_scene = DeviceScene(queue, scene, bvh=bvh)
        per_scene = report["scenes"][scene.name] = {}
        for name in techniques:
            n = spp if get_technique(name)[0].family == "pt" else max(1, spp // 8)
            techs, entry = {}, {}
            for kernels in KERNELS:
                if progress:
                    progress(f"{scene.name} {name} {kernels}: uncached build and warm-up")
                techs[kernels], entry[kernels] = _build(queue, device_scene, name, kernels == "general")
                start = time.perf_counter()
                techs[kernels].render(width, height, n, seed=10**6)
                entry[kernels]["warmup_seconds"] = time.perf_counter() - start
                entry[kernels]["runs"] = []
            for r in range(repeats):
                for kernels in KERNELS:
                    entry[kernels]["runs"].append(_samples_per_second(techs[kernels], width, height, n, r))
            for kernels in KERNELS:
                entry[kernels]["samples_per_second"] = statistics.median(entry[kernels]["runs"])
            entry["speedup"] = entry["specialized"]["samples_per_second"] / entry["general"]["samples_per_second"]
            per_scene[name] = entry
    return report


def format_specialization(report):
    """A table per scene: samples/s, build time and binary size of both kernels."""
    w, h = report["resolution"]
    lines = [f"Specialized kernels (only what the scene uses) against the general kernel (everything "
             f"compiled in), on {report['device']}, {w}x{h}, median of {report['repeats']} runs; "
             f"builds uncached"]
    head = (f"  {'technique':24s} {'samples/s spec.':>15s} {'general':>11s} {'speed-up':>9s}"
            f" {'build s spec.':>13s} {'general':>8s} {'binary KiB spec.':>16s} {'general':>8s}")
    for scene, techniques in report["scenes"].items():
        lines += [f"{scene}:", head]
        for name, e in techniques.items():
            s, g = e["specialized"], e["general"]
            lines.append(f"  {name:24s} {s['samples_per_second']:15,.0f} {g['samples_per_second']:11,.0f}"
                         f" {e['speedup']:8.2f}x {s['build_seconds']:13.2f} {g['build_seconds']:8.2f}"
                         f" {s['binary_bytes'] / 1024:16.0f} {g['binary_bytes'] / 1024:8.0f}")
    lines.append("speed-up: specialized / general samples/s; build: clBuildProgram, uncached (PoCL compiles "
                 "each kernel's work-group code at its first launch: the JSON's warmup_seconds)")
    return "\n".join(lines)
