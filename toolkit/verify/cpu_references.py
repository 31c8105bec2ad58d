"""CPU reference images for a machine that has no CPU OpenCL (the offline GPU machine, issue 38).

gpucheck's same-image step compares this device's images with another OpenCL implementation's
on the same samples. A GPU machine without a CPU runtime has nothing to compare with, so the
images are rendered here, on a CPU, and carried there:

    python -m toolkit gpucheck --write-cpu-references .gpu/cpu_references     # here, on a CPU
    python -m toolkit gpucheck --device gpu                                   # there

gpucheck uses `--cpu-references DIR`, or DEFAULT_FOLDER when it exists. The folder holds
`references.json` (what was rendered, where, and each image's file) and one `.npy` per image.
Random numbers are keyed by (seed, pixel, sample, dimension), so the GPU renders the same
samples; the images must agree within same_image.ACROSS_IMPLEMENTATIONS, up to FLIPS_ALLOWED of
the pixels (the same bound as between PoCL and Intel's runtime; same_image.py says why).

The folder is input from elsewhere: every entry is checked (a bundled scene, a known technique,
bounded sizes, a plain file name inside the folder, an image of the right shape) before any
render, and a bad one is an InputError that names it.
"""
import datetime
import json
import re
from pathlib import Path

import numpy as np

from toolkit import api
from toolkit.core.scene import bundled_scene_dir, bundled_scene_names
from toolkit.core.validate import InputError
from toolkit.opencl import device as devices
from toolkit.techniques import family, get_technique
from toolkit.verify.same_image import ACROSS_IMPLEMENTATIONS, FLIPS_ALLOWED, compare_images

DEFAULT_FOLDER = Path(".gpu/cpu_references")   # beside the GPU machine's wheels (shared/gpu/README.md)
MANIFEST = "references.json"
SEED = 3
# (scene, technique, side, spp): every technique of both families on the Cornell box, the best of
# each on the spheres. 64x64 holds 4,096 pixels, so FLIPS_ALLOWED lets 4 of them differ by a
# near tie; BDPT at 1 spp costs about what PT does at 8.
RENDERS = [("cornell_box", name, 64, 1 if name.startswith("bdpt") else 8)
           for name in ("pt_naive", "pt_inplace_regen", "pt_compact_regen", "pt_compact_regen/multipass",
                        "bdpt_naive_connect", "bdpt_parallel_connect", "bdpt_parallel_connect/direct_scatter")]
RENDERS += [("cornell_spheres", "pt_compact_regen", 64, 8), ("cornell_spheres", "bdpt_parallel_connect", 64, 1)]
MAX_SIDE, MAX_SPP, MAX_ENTRIES = 512, 64, 64


def file_name(scene, technique):
    return f"{scene}__{technique.replace('/', '__')}.npy"


def write(folder, device=None, log=print):
    """Render RENDERS on `device` (a CPU) into `folder`; returns the manifest written."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    queue = devices.get_queue(device)
    entries = []
    for scene, technique, side, spp in RENDERS:
        log(f"{technique} on {scene}, {side}x{side}, {spp} spp")
        image = api.render(bundled_scene_dir(scene), technique=technique, spp=spp, seed=SEED, resolution=(side, side),
                           device=device, count_simd=False).image
        if not np.isfinite(image).all():
            raise RuntimeError(f"{technique} on {scene}: non-finite pixels in the CPU reference")
        name = file_name(scene, technique)
        np.save(folder / name, image.astype(np.float64), allow_pickle=False)
        entries.append({"scene": scene, "technique": technique, "resolution": [side, side], "spp": spp,
                        "seed": SEED, "file": name})
    manifest = {"device": devices.describe(queue.device), "implementation": devices.describe_implementation(queue.device),
                "written": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                "entries": entries}
    (folder / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")
    return manifest


def load(folder):
    """The manifest of `folder`, every entry checked, with each image loaded (entry["image"])."""
    folder = Path(folder)
    path = folder / MANIFEST
    try:
        manifest = json.loads(path.read_text())
    except (OSError, ValueError) as error:
        raise InputError(f"CPU references {folder}: cannot read {MANIFEST}: {error}") from None
    entries = manifest.get("entries") if isinstance(manifest, dict) else None
    if not isinstance(entries, list) or not 0 < len(entries) <= MAX_ENTRIES:
        raise InputError(f"CPU references {path}: 'entries' must be a list of 1 to {MAX_ENTRIES} renders")
    return manifest | {"entries": [_checked_entry(folder, i, e) for i, e in enumerate(entries)]}


def _checked_entry(folder, i, entry):
    where = f"CPU references {folder / MANIFEST}, entry {i}"
    if not isinstance(entry, dict):
        raise InputError(f"{where}: not an object")
    scene, technique, file = entry.get("scene"), entry.get("technique"), entry.get("file")
    if scene not in bundled_scene_names():
        raise InputError(f"{where}: scene {scene!r} is not a bundled scene ({', '.join(bundled_scene_names())})")
    try:
        get_technique(technique)
    except (ValueError, TypeError):
        raise InputError(f"{where}: unknown technique {technique!r}") from None
    if family(technique) == "mlt":
        raise InputError(f"{where}: mlt's samples depend on its chain count, so its image is no reference")
    resolution, spp, seed = entry.get("resolution"), entry.get("spp"), entry.get("seed")
    if not (isinstance(resolution, list) and len(resolution) == 2
            and all(type(x) is int and 0 < x <= MAX_SIDE for x in resolution)):
        raise InputError(f"{where}: resolution must be [width, height], each 1 .. {MAX_SIDE}")
    if type(spp) is not int or not 0 < spp <= MAX_SPP or type(seed) is not int or not 0 <= seed < 2**31:
        raise InputError(f"{where}: spp must be 1 .. {MAX_SPP} and seed a whole number 0 .. 2^31-1")
    # The image's file: a plain name inside the folder, never a path that leaves it.
    if not isinstance(file, str) or not re.fullmatch(r"[A-Za-z0-9_.-]+\.npy", file):
        raise InputError(f"{where}: file must be a plain .npy name in the folder, got {file!r}")
    path = folder / file
    if path.is_symlink() or not path.resolve().is_relative_to(folder.resolve()):
        raise InputError(f"{where}: {file} is a link; the images must be files in the folder")
    try:
        # mapped, not read: the shape is checked before a byte of a file of any size is loaded
        image = np.load(path, mmap_mode="r", allow_pickle=False)
    except (OSError, ValueError) as error:
        raise InputError(f"{where}: cannot read {file}: {error}") from None
    width, height = resolution
    if image.shape != (height, width, 3) or image.dtype.kind != "f":
        raise InputError(f"{where}: {file} holds {image.dtype} {image.shape}, expected a float ({height}, {width}, 3)")
    return {"scene": scene, "technique": technique, "resolution": (width, height), "spp": spp, "seed": seed,
            "image": np.array(image, np.float64)}


def checks(folder, device=None, log=None):
    """One Check per reference: this device's image on the same samples against the CPU's."""
    manifest = load(folder)
    found = []
    for e in manifest["entries"]:
        if log:
            log(f"{e['technique']} on {e['scene']} against {manifest.get('implementation', 'the CPU')}")
        image = api.render(bundled_scene_dir(e["scene"]), technique=e["technique"], spp=e["spp"], seed=e["seed"],
                           resolution=e["resolution"], device=device, count_simd=False).image
        found.append(compare_images(f"{e['technique']} on {e['scene']} = the CPU reference "
                                    f"({e['resolution'][0]}x{e['resolution'][1]}, {e['spp']} spp)",
                                    image, e["image"], ACROSS_IMPLEMENTATIONS, FLIPS_ALLOWED))
    return found
