"""`python -m toolkit bench --peer embree|mitsuba`: the toolkit beside the renderer a learner
would otherwise pick, measured in one run on one machine.

- `embree`: closest-hit rays per second of our BVH traversal (toolkit/opencl/raycast.py, both the
  binary and the wide BVH) against Embree (embreex) on the same float32 rays: random rays
  (toolkit/verify/crosscheck.py) and the camera's pixel-centre rays. Both are timed from host arrays
  to host results, repetitions interleaved, medians.
- `mitsuba`: Mitsuba 3's `path` integrator on the scene converted by `to_mitsuba` (which
  follows scenes/FORMAT.md), and the toolkit's techniques, with per technique: samples per
  pixel per second, the variance of one sample (from independent repetitions) and the time
  to reach 5% RMSE.

Mitsuba is an optional extra: `pip install ".[peers]"`.
"""
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from toolkit.api import as_scene, render
from toolkit.core.validate import camera_size
from toolkit.core.stats import rmse
from toolkit.opencl.device import get_queue
from toolkit.opencl.device_scene import DeviceScene
from toolkit.opencl.raycast import DeviceRaycaster
from toolkit.peers.embree import EmbreeIntersector, camera_rays, random_rays, surface_rays
from toolkit.techniques import family

PEERS = ("embree", "mitsuba")
INSTALL_HINT = ("Mitsuba 3 is not installed: it is an optional extra of the toolkit. Install it with\n"
                "  pip install \".[peers]\"      (from the toolkit's folder; or: pip install \"mitsuba>=3.9,<3.10\")")
TARGET_RMSE = 0.05
PEER_DEFAULT = ("pt_naive", "pt_compact_regen", "bdpt_parallel_connect")   # techniques beside Mitsuba


class PeerMissing(RuntimeError):
    """The peer renderer is not installed (the message says how to install it)."""


# ---- embree ----------------------------------------------------------------------------------

def embree_rays(scene, n_random=262_144, repeats=5, seed=0, queue=None, bvhs=("binary", "wide")):
    """Closest-hit rays/s of our traversal (each BVH in `bvhs`) and of Embree on the same rays:
    {"random": {name: rays/s}, "camera": {...}, "surface": {...}}, medians of `repeats` interleaved
    runs. The rays (embree.py): n_random from random points in and around the box, one per pixel
    from the camera, and n_random from the surfaces."""
    width, height = camera_size(scene.camera.width, scene.camera.height)   # render's memory estimate, first
    queue = queue or get_queue()
    casters = {}
    for bvh in bvhs:
        ds = DeviceScene(queue, scene, bvh=bvh)
        casters[f"toolkit {bvh}"] = DeviceRaycaster(queue, ds).closest
    embree = EmbreeIntersector(scene, center=ds.center)
    casters["embreex"] = embree.closest
    rays = {"random": random_rays(ds, n_random, np.random.default_rng(seed)),
            "camera": camera_rays(ds, width, height),
            "surface": surface_rays(ds, n_random, np.random.default_rng(seed + 1))}
    rates = {kind: {name: [] for name in casters} for kind in rays}
    for kind, (o, d) in rays.items():
        for cast in casters.values():      # warm-up (first launch compiles on PoCL)
            cast(o[:1024], d[:1024])
    for _ in range(repeats):
        for kind, (o, d) in rays.items():
            for name, cast in casters.items():
                start = time.perf_counter()
                cast(o, d)
                rates[kind][name].append(len(o) / (time.perf_counter() - start))
    return {"scene": scene.name, "repeats": repeats,
            "rays": {kind: len(o) for kind, (o, _) in rays.items()},
            "rays_per_second": {kind: {n: statistics.median(v) for n, v in r.items()} for kind, r in rates.items()}}


def format_embree(report):
    lines = [f"closest-hit rays/s on {report['scene']}, median of {report['repeats']} interleaved runs "
             f"(host arrays in, results out; " +
             ", ".join(f"{n:,} {k} rays" for k, n in report["rays"].items()) + ")"]
    names = list(next(iter(report["rays_per_second"].values())))
    lines.append(f"{'rays':<8}" + "".join(f"{n:>18}" for n in names) +
                 "".join(f"{n.split()[-1] + ' / embree':>16}" for n in names if n != "embreex"))
    for kind, row in report["rays_per_second"].items():
        lines.append(f"{kind:<8}" + "".join(f"{row[n] / 1e6:>16.2f} M" for n in names) +
                     "".join(f"{row[n] / row['embreex']:>16.2f}" for n in names if n != "embreex"))
    return "\n".join(lines)


# ---- mitsuba ---------------------------------------------------------------------------------

# A render in a child process: an LLVM too old for Dr.Jit's IR aborts the whole process
# ("LLVM ERROR: Cannot select"), so the LLVM variant is tried where a crash costs nothing.
_PROBE = """
import mitsuba as mi, numpy as np
mi.set_variant("llvm_ad_rgb")
s = mi.load_dict({"type": "scene", "integrator": {"type": "path"},
                  "sensor": {"type": "perspective", "film": {"type": "hdrfilm", "width": 8, "height": 8}},
                  "shape": {"type": "sphere", "center": [0, 0, 5], "emitter": {"type": "area"}}})
assert np.isfinite(np.array(mi.render(s, spp=1))).all()
"""
_variant = None


def load_mitsuba():
    """(the mitsuba module, the variant set, why not LLVM or None): llvm_ad_rgb where it renders
    (it needs a recent libLLVM; Dr.Jit's DRJIT_LIBLLVM_PATH names one), else scalar_rgb.
    Raises PeerMissing without Mitsuba."""
    global _variant
    try:
        # Optional: Mitsuba is the [peers] extra, needed only to compare with it.
        import mitsuba as mi
    except ImportError:
        raise PeerMissing(INSTALL_HINT) from None
    if _variant is None:
        probe = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, timeout=300)
        if probe.returncode == 0:
            _variant = ("llvm_ad_rgb", None)
        else:
            lines = [l for l in (probe.stderr or "").splitlines() if "ERROR" in l or "Error" in l]
            _variant = ("scalar_rgb", "llvm_ad_rgb did not render here (" + (lines[0].strip()[:120] if lines else
                        f"exit {probe.returncode}") + "); set DRJIT_LIBLLVM_PATH to a newer libLLVM")
    mi.set_variant(_variant[0])
    return mi, _variant[0], _variant[1]


def _write_ply(path, vertices, faces):
    """A binary little-endian PLY of float32 vertices and int32 triangles."""
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(vertices)}\n"
              "property float x\nproperty float y\nproperty float z\n"
              f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    face_rows = np.zeros(len(faces), np.dtype([("n", "u1"), ("v", "<i4", (3,))]))
    face_rows["n"], face_rows["v"] = 3, faces
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(np.asarray(vertices, "<f4").tobytes())
        f.write(face_rows.tobytes())


def _bsdf(material):
    """A scenes/FORMAT.md material as a Mitsuba BSDF dict."""
    rgb = {"type": "rgb", "value": [float(x) for x in material["reflectance"]]}
    kind = material["type"]
    if kind == "diffuse":
        bsdf = {"type": "diffuse", "reflectance": rgb}
    elif kind == "mirror":       # perfect specular reflection, no Fresnel: a conductor of material "none"
        bsdf = {"type": "conductor", "material": "none", "specular_reflectance": rgb}
    elif kind == "glossy":       # GGX, Smith G1(wi) G1(wo), F = 1
        bsdf = {"type": "roughconductor", "material": "none", "distribution": "ggx",
                "alpha": float(material["alpha"]), "specular_reflectance": rgb}
    elif kind == "dielectric":   # the face normal points to the exterior (index 1)
        return {"type": "dielectric", "int_ior": float(material["ior"]), "ext_ior": 1.0}
    else:
        raise ValueError(f"no Mitsuba conversion for material type {kind!r}")
    return {"type": "twosided", "bsdf": bsdf}     # FORMAT.md: two-sided except dielectrics


INTEGRATORS = ("path", "ptracer")


def to_mitsuba(scene, folder, width=None, height=None, spp=16, integrator="path"):
    """A Mitsuba 3 scene dict for `scene` (FORMAT.md's conventions): pinhole camera with the same
    field of view, a box filter one pixel wide, the `integrator` (`path`, or `ptracer`: Mitsuba's
    light tracer, for scenes whose light reaches the camera's room through a narrow opening) with
    the scene's max_depth and rr_depth, one-sided area lights, geometric normals. Meshes are
    written as PLY files to `folder`, one per (material, emission) group of triangles."""
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator must be one of {', '.join(INTEGRATORS)}, got {integrator!r}")
    width, height = width or scene.camera.width, height or scene.camera.height
    if scene.clamp is not None:
        raise ValueError(f"{scene.name}: integrator.clamp has no counterpart in Mitsuba's path integrator; "
                         "compare without it")
    cam = scene.camera
    rr_depth = scene.rr_depth if scene.rr_depth >= 0 else 1 << 30          # -1: no roulette
    out = {
        "type": "scene",
        "integrator": {"type": integrator, "max_depth": int(scene.max_depth), "rr_depth": int(rr_depth),
                       "hide_emitters": False},
        "sensor": {
            "type": "perspective", "fov": float(cam.fov_deg), "fov_axis": cam.fov_axis,
            "near_clip": 1e-6 * scene.extent, "far_clip": 1e6 * scene.extent,
            "to_world": {"type": "look_at_placeholder"},
            "film": {"type": "hdrfilm", "width": int(width), "height": int(height),
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": int(spp)},
        },
    }
    groups = {}
    for t, (m, e) in enumerate(zip(scene.material_of, map(tuple, scene.emission_of))):
        groups.setdefault((int(m), e), []).append(t)
    for i, ((m, emission), tris) in enumerate(sorted(groups.items())):
        used = scene.triangles[tris]
        keep, faces = np.unique(used, return_inverse=True)
        path = Path(folder) / f"shape_{i}.ply"
        _write_ply(path, scene.vertices[keep], faces.reshape(-1, 3))
        shape = {"type": "ply", "filename": str(path), "face_normals": True, "bsdf": _bsdf(scene.materials[m])}
        if max(emission) > 0:
            shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": [float(x) for x in emission]}}
        out[f"shape_{i}"] = shape
    return out


# The element of each object key in to_mitsuba's dict (shape_0, shape_1, ...: <shape>).
_XML_OBJECTS = ("integrator", "sensor", "film", "rfilter", "sampler", "bsdf", "emitter", "shape")


def write_mitsuba_xml(scene, folder, width=None, height=None, spp=16, integrator="path"):
    """`scene` as a Mitsuba 3 XML file, folder/scene.xml, with its meshes beside it: to_mitsuba's
    scene written out, the camera by a <lookat>, every float in Python's repr (it reads back to
    the same float64). toolkit/core/mitsuba_scene.py reads it back as the same scene
    (tests/test_mitsuba_xml.py); Mitsuba renders it with mi.load_file. Returns the path."""
    folder = Path(folder)
    description = to_mitsuba(scene, folder, width, height, spp, integrator)
    for key, shape in description.items():      # filenames relative to the scene file, as Mitsuba resolves them
        if key.startswith("shape_"):
            shape["filename"] = Path(shape["filename"]).name
    cam = scene.camera
    lines = ['<scene version="3.0.0">']
    for key, value in description.items():
        if key != "type":
            lines += _xml_element(key, value, cam, "    ")
    path = folder / "scene.xml"
    path.write_text("\n".join(lines + ["</scene>", ""]), encoding="utf-8")
    return path


def _xml_value(x):
    return repr(float(x))


def _xml_element(name, value, cam, indent):
    """The lines of one property or object of to_mitsuba's dict."""
    if isinstance(value, dict) and value.get("type") == "look_at_placeholder":
        xyz = [", ".join(map(_xml_value, v)) for v in (cam.origin, cam.target, cam.up)]
        return [f'{indent}<transform name="{name}">',
                f'{indent}    <lookat origin="{xyz[0]}" target="{xyz[1]}" up="{xyz[2]}"/>', f"{indent}</transform>"]
    if isinstance(value, dict) and value.get("type") == "rgb":
        return [f'{indent}<rgb name="{name}" value="{", ".join(map(_xml_value, value["value"]))}"/>']
    if isinstance(value, dict):
        tag = next(t for t in _XML_OBJECTS if name == t or name.startswith(t + "_"))
        lines = [f'{indent}<{tag} type="{value["type"]}">']
        for key, inner in value.items():
            if key != "type":
                lines += _xml_element(key, inner, cam, indent + "    ")
        return lines + [f"{indent}</{tag}>"]
    if isinstance(value, bool):
        return [f'{indent}<boolean name="{name}" value="{str(value).lower()}"/>']
    if isinstance(value, int):
        return [f'{indent}<integer name="{name}" value="{value}"/>']
    if isinstance(value, float):
        return [f'{indent}<float name="{name}" value="{_xml_value(value)}"/>']
    return [f'{indent}<string name="{name}" value="{value}"/>']


def _camera_transform(mi, cam):
    return mi.ScalarTransform4f().look_at(origin=[float(x) for x in cam.origin],
                                          target=[float(x) for x in cam.target],
                                          up=[float(x) for x in cam.up])


class MitsubaRenderer:
    """A converted scene loaded into Mitsuba once; `render(spp, seed)` returns (image, seconds)."""

    def __init__(self, scene, width=None, height=None, integrator="path"):
        self.mi, self.variant, self.why_not_llvm = load_mitsuba()
        self._folder = tempfile.TemporaryDirectory(prefix="toolkit_mitsuba_")
        description = to_mitsuba(scene, self._folder.name, width, height, integrator=integrator)
        self.integrator = description["integrator"]
        description["sensor"]["to_world"] = _camera_transform(self.mi, scene.camera)
        self.scene = self.mi.load_dict(description)

    def render(self, spp, seed=0):
        start = time.perf_counter()
        image = np.array(self.mi.render(self.scene, spp=int(spp), seed=int(seed)), np.float64)[..., :3]
        return image, time.perf_counter() - start

    def passes(self, spp, passes, seed=0):
        """(mean image, per-pixel standard error, seconds) from `passes` independent renders."""
        images, seconds = [], 0.0
        for k in range(passes):
            image, s = self.render(spp, seed=seed + k)
            images.append(image)
            seconds += s
        images = np.stack(images)
        return images.mean(0), images.std(0, ddof=1) / np.sqrt(passes), seconds


def mitsuba_bench(scene, techniques=PEER_DEFAULT, spp=16,
                  repeats=4, resolution=None, device=None, bvh="wide", seed=0, reference_at=None):
    """Mitsuba `path` and the toolkit's techniques on one scene, repetitions interleaved.
    Per renderer: spp/s (median), variance per sample (mean over pixels and channels of the
    variance between repetitions, times their spp), time to 5% RMSE (relative to the reference's
    mean: (variance per sample / (0.05 mean)^2) samples per pixel at the measured spp/s), and the
    RMSE of the repetitions' mean image against the reference. `reference_at(scene, width, height)`
    gives the reference image (or None) and its standard error: toolkit.measure.reference's, which
    `bench --peer mitsuba` passes (peers and measure are siblings); None: no reference, no RMSE."""
    scene = as_scene(scene)
    width, height = resolution or (scene.camera.width, scene.camera.height)
    ref = reference_at(scene, width, height)[0] if reference_at else None
    peer = MitsubaRenderer(scene, width, height)
    runners = {f"mitsuba {peer.variant} path": ("mitsuba", spp)}
    for name in techniques:
        runners[f"toolkit {name}"] = (name, max(1, spp // 8) if family(name) == "bdpt" else spp)

    def run(name, r):
        what, n = runners[name]
        if what == "mitsuba":
            image, seconds = peer.render(n, seed=seed + r)
        else:
            result = render(scene, technique=what, spp=n, seed=seed + r, resolution=(width, height),
                            device=device, count_simd=False, bvh=bvh)
            image, seconds = result.image, result.stats["seconds"]
        return image, seconds

    for name in runners:          # warm-up: kernel builds, Mitsuba's JIT, BVHs
        run(name, 1000)
    images = {name: [] for name in runners}
    rates = {name: [] for name in runners}
    for r in range(repeats):
        for name in runners:
            image, seconds = run(name, r)
            images[name].append(image)
            rates[name].append(runners[name][1] / seconds)
    rows = {}
    mean_ref = float(ref.mean()) if ref is not None else None
    for name in runners:
        stack = np.stack(images[name])
        n = runners[name][1]
        var_per_sample = float(stack.var(0, ddof=1).mean() * n)
        sps = statistics.median(rates[name])
        row = {"spp": n, "spp_per_second": sps, "runs": rates[name], "variance_per_sample": var_per_sample}
        if ref is not None:
            needed = var_per_sample / (TARGET_RMSE * mean_ref) ** 2
            row.update(spp_to_target=needed, seconds_to_target=needed / sps,
                       rmse_of_mean=rmse(stack.mean(0), ref) / mean_ref)
        rows[name] = row
    return {"scene": scene.name, "resolution": [width, height], "repeats": repeats, "bvh": bvh,
            "variant": peer.variant, "why_not_llvm": peer.why_not_llvm, "rows": rows}


def format_mitsuba(report):
    w, h = report["resolution"]
    lines = [f"peer bench: {report['scene']} {w}x{h}, median of {report['repeats']} interleaved repetitions "
             f"(independent seeds), kernel builds and Mitsuba's JIT excluded; Mitsuba variant {report['variant']}, "
             f"toolkit {report['bvh']} BVH",
             f"{'renderer':<44}{'spp':>5}{'spp/s':>9}{'var/sample':>12}{'s to 5% RMSE':>14}{'rel RMSE':>10}"]
    base = None
    for name, row in report["rows"].items():
        base = base or row["spp_per_second"]
        t = f"{row['seconds_to_target']:>14.1f}" if "seconds_to_target" in row else f"{'-':>14}"
        e = f"{row['rmse_of_mean']:>10.4f}" if "rmse_of_mean" in row else f"{'-':>10}"
        lines.append(f"{name:<44}{row['spp']:>5}{row['spp_per_second']:>9.2f}{row['variance_per_sample']:>12.5f}{t}{e}")
    if report.get("why_not_llvm"):
        lines.insert(1, f"  note: {report['why_not_llvm']}")
    first = next(iter(report["rows"]))
    for name, row in report["rows"].items():
        if name != first:
            lines.append(f"  {name} spp/s / Mitsuba: {row['spp_per_second'] / report['rows'][first]['spp_per_second']:.2f}")
    lines.append("var/sample: per-pixel variance of one sample (between repetitions, x their spp), mean over "
                 "pixels and channels; s to 5% RMSE: time until the RMSE, relative to the reference's mean, is 5% "
                 "(var/sample / (0.05 mean)^2 spp at the measured spp/s); rel RMSE: the repetitions' mean image "
                 "against the reference (which has its own noise, ~2.5% per pixel).")
    return "\n".join(lines)
