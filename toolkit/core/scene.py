"""Scenes in the interchange format `toolkit-scene/1` (scenes/FORMAT.md), validated.

A `Scene` holds float64 numpy arrays on the host; `features()` says which code the kernels need.
"""
import json
import math
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from toolkit.core.build_process import start_early as start_bvh_build_early
from toolkit.core.images import read_exr
from toolkit.core.layout import MATERIAL_TYPES
from toolkit.core.mesh_files import read_mesh
from toolkit.core.mitsuba_scene import check_clipping, read_mitsuba
from toolkit.core.obj import ObjError
from toolkit.core.transforms import camera_frame, checked, compose, operations_from_json, place_mesh
from toolkit.core.package_data import data_dir
from toolkit.core.validate import LIMITS, InputError, check_keys, finite_number, in_range, json_depth, \
    regular_file_inside, utf8_path, whole_number

FORMAT = "toolkit-scene/1"
# The parameters of each material type (MATERIAL_TYPES: the codes shared with the kernels as MAT_*,
# MaterialType in toolkit/core/layout.py).
MATERIAL_PARAMS = {"diffuse": {"reflectance"}, "mirror": {"reflectance"},
                   "dielectric": {"ior"}, "glossy": {"reflectance", "alpha"}}
# The keys of each object in scene.json (a free-form "notes" is allowed in every one).
TOP_KEYS = {"format", "camera", "materials", "shapes", "integrator"}
CAMERA_KEYS = {"origin", "target", "up", "transform", "fov_deg", "fov_axis", "width", "height"}
SHAPE_KEYS = {"mesh", "material", "emission", "transform"}
INTEGRATOR_KEYS = {"max_depth", "rr_depth", "clamp"}
# A depth the general kernel (features(general=True)) compares with where the scene sets no
# limit: far beyond HARD_MAX_BOUNCES (toolkit/core/layout.py), so the test is compiled in but never fires.
NO_LIMIT = 1 << 30


class SceneError(InputError):
    """A scene that cannot be rendered, with the file and the problem named."""


@dataclass
class Camera:
    origin: np.ndarray
    target: np.ndarray
    up: np.ndarray
    fov_deg: float
    fov_axis: str
    width: int
    height: int

    def basis(self, width=None, height=None):
        """(forward, right*tx, up*ty) as in FORMAT.md, for an image of width x height."""
        width, height = width or self.width, height or self.height
        f = self.target - self.origin
        f = f / np.linalg.norm(f)
        r = np.cross(f, self.up)
        r = r / np.linalg.norm(r)
        u = np.cross(r, f)
        t = math.tan(math.radians(self.fov_deg) / 2)
        tx, ty = (t, t * height / width) if self.fov_axis == "x" else (t * width / height, t)
        return f, r * tx, u * ty


@dataclass
class Scene:
    name: str
    camera: Camera
    vertices: np.ndarray            # (N, 3) float64
    triangles: np.ndarray           # (M, 3) int64
    material_of: np.ndarray         # (M,) material index per triangle
    emission_of: np.ndarray         # (M, 3) emitted radiance per triangle (0: not a light)
    materials: list                 # [{"name", "type", "reflectance", "ior", "alpha"}]
    max_depth: int = -1
    rr_depth: int = 5
    clamp: float = None             # firefly clamping (FORMAT.md): None = off, unbiased
    path: Path = None
    reference: np.ndarray = None    # (H, W, 3) float32 or None
    reference_stderr: np.ndarray = None
    dropped_triangles: int = 0
    info: dict = field(default_factory=dict)

    @property
    def extent(self):
        """Length of the bounding-box diagonal: the scale every epsilon is relative to."""
        lo, hi = self.vertices.min(0), self.vertices.max(0)
        return float(np.linalg.norm(hi - lo))

    def features(self, general=False):
        """Compile-time defines: only what this scene uses is built into the kernels.

        `general=True`: the general kernel instead, as a renderer that does not specialize
        would build it: every material and the specular paths compiled in, the depth limit and
        Russian roulette tests always there. The limits stay numbers in the build (the scene's
        own; NO_LIMIT where it has none, a test that never fires), so both kernels compute the
        same image (tests/test_specialization.py) and differ only in the code they carry."""
        used = {self.materials[i]["type"] for i in np.unique(self.material_of)}
        defines = {}
        for name in MATERIAL_TYPES:
            defines[f"HAS_{name.upper()}"] = general or name in used
        defines["HAS_SPECULAR"] = general or bool(used & {"mirror", "dielectric"})
        defines["MAX_DEPTH"] = self.max_depth if self.max_depth >= 0 or not general else NO_LIMIT
        defines["USE_MAX_DEPTH"] = general or self.max_depth >= 0
        defines["RR_DEPTH"] = self.rr_depth if self.rr_depth >= 0 or not general else NO_LIMIT
        defines["USE_RUSSIAN_ROULETTE"] = general or (self.rr_depth >= 0 and self.max_depth != 0)
        # Firefly clamping: BDPT caps each connection on the device (cl/bdpt.h), so both connect
        # phases clamp the same values; the path tracers clamp a whole sample where the film sums
        # them (cl/film_reduce.cl). Defined only when set: other scenes build unchanged.
        if self.clamp is not None:
            defines["CLAMP"] = float(self.clamp)
        return defines

    def transformed(self, scale=1.0, translate=(0.0, 0.0, 0.0)):
        """The same scene scaled about the origin then translated (numerical-stability tests)."""
        t = np.asarray(translate, np.float64)
        cam = replace(self.camera, origin=self.camera.origin * scale + t,
                      target=self.camera.target * scale + t)
        return replace(self, vertices=self.vertices * scale + t, camera=cam,
                       name=f"{self.name} (x{scale:g} +{tuple(t)})")

    def with_resolution(self, width, height):
        return replace(self, camera=replace(self.camera, width=int(width), height=int(height)))

    @property
    def light_triangles(self):
        return np.flatnonzero(self.emission_of.max(1) > 0)


def _fail(where, message):
    raise SceneError(f"{where}: {message}")


def _vector(where, value, n=3, positive=False):
    try:
        v = np.asarray(value, np.float64)
    except (TypeError, ValueError, OverflowError):
        _fail(where, f"expected {n} finite numbers, got {_short(value)}")
    if v.shape != (n,) or isinstance(value, (str, dict)) or any(isinstance(x, bool) for x in value):
        _fail(where, f"expected {n} numbers, got {_short(value)}")
    if not np.all(np.isfinite(v)):
        _fail(where, f"NaN or infinite value in {value!r}")
    if positive and np.any(v < 0):
        _fail(where, f"negative value in {value!r}")
    return v


def _short(value, n=60):
    text = repr(value)
    return text if len(text) <= n else text[:n] + "..."


def _number(where, value, limit):
    """A finite number within LIMITS[limit]."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        _fail(where, f"expected a finite number, got {_short(value)}")
    if isinstance(value, float) and not math.isfinite(value):
        _fail(where, f"expected a finite number, got {value!r}")
    return finite_number(limit, value, where)


def _object(where, value, what, known):
    if not isinstance(value, dict):
        _fail(where, f"{what} must be an object, got {_short(value)}")
    check_keys(where, value, known, what)
    return value


def _parse_camera(where, cam):
    if not isinstance(cam, dict):
        _fail(where, "'camera' must be an object")
    check_keys(where, cam, CAMERA_KEYS, "the camera")
    placement = ("transform",) if "transform" in cam else ("origin", "target", "up")
    if "transform" in cam and {"origin", "target", "up"} & set(cam):
        _fail(where, "the camera is placed either by origin, target and up or by a transform, not both")
    for key in (*placement, "fov_deg", "width", "height"):
        if key not in cam:
            _fail(where, f"camera has no '{key}'")
    if "transform" in cam:      # Mitsuba's sensor to_world: usually one look_at
        origin, target, up = camera_frame(checked(compose(operations_from_json(
            f"{where}: camera.transform", cam["transform"])), f"{where}: camera"), f"{where}: camera.transform")
    else:
        origin, target, up = (_vector(f"{where}: camera.{key}", cam[key]) for key in ("origin", "target", "up"))
    camera = Camera(
        origin=origin, target=target, up=up,
        fov_deg=_number(f"{where}: camera.fov_deg", cam["fov_deg"], "camera.fov_deg"),
        fov_axis=cam.get("fov_axis", "x"),
        width=whole_number("camera.width", cam["width"], f"{where}: camera.width"),
        height=whole_number("camera.height", cam["height"], f"{where}: camera.height"))
    if not isinstance(camera.fov_axis, str) or camera.fov_axis not in ("x", "y"):
        _fail(where, f"camera.fov_axis must be 'x' or 'y', got {_short(camera.fov_axis)}")
    f = camera.target - camera.origin
    if np.linalg.norm(f) == 0:
        _fail(where, "camera.target equals camera.origin")
    if np.linalg.norm(np.cross(f, camera.up)) <= 1e-9 * np.linalg.norm(f) * np.linalg.norm(camera.up):
        _fail(where, "camera.up is parallel to the viewing direction")
    return camera


def _parse_material(where, name, m):
    if not isinstance(m, dict) or "type" not in m:
        _fail(where, f"material {name!r} needs a 'type'")
    kind = m["type"]
    if not isinstance(kind, str) or kind not in MATERIAL_TYPES:
        _fail(where, f"material {name!r} has unknown type {_short(kind)} "
                     f"(known: {', '.join(MATERIAL_TYPES)})")
    check_keys(where, m, {"type"} | MATERIAL_PARAMS[kind], f"material {name!r} ({kind})")
    missing = MATERIAL_PARAMS[kind] - set(m)
    if missing:
        _fail(where, f"material {name!r} ({kind}) is missing {', '.join(sorted(missing))}")
    out = {"name": name, "type": kind, "reflectance": np.zeros(3), "ior": 1.0, "alpha": 0.0}
    if "reflectance" in MATERIAL_PARAMS[kind]:
        out["reflectance"] = _vector(f"{where}: material {name!r}.reflectance", m["reflectance"], positive=True)
        if np.any(out["reflectance"] > LIMITS["material.reflectance"][1]):
            _fail(where, f"material {name!r}: reflectance above 1 creates energy")
    if kind == "dielectric":
        out["ior"] = _number(f"{where}: material {name!r}.ior", m["ior"], "material.ior")
    if kind == "glossy":
        out["alpha"] = _number(f"{where}: material {name!r}.alpha", m["alpha"], "material.alpha")
    return out


def _no_duplicates(pairs):
    keys = [k for k, _ in pairs]
    for k in keys:
        if keys.count(k) > 1:
            raise SceneError(f"key {k!r} appears twice in one object (the second would silently win)")
    return dict(pairs)


def load_scene(path):
    """Load and validate a scene folder, its scene.json or a Mitsuba 3 XML file; raises SceneError
    naming the problem."""
    try:
        return _load_scene(path)
    except SceneError:
        raise
    except InputError as error:      # from the shared checks in validate.py
        raise SceneError(str(error)) from None


def find_scene(given):
    """Where the scene a command names is: `given` itself where it exists (a folder, its
    scene.json), else the bundled scene of that name (`render cornell_spheres`), else a
    SceneError. The one resolver of every command and of toolkit.render."""
    path = utf8_path(given, "scene")
    if path.exists() or path.is_symlink():
        return path
    if path.name == str(given) and path.name in bundled_scene_names():      # a bare name, not a path
        return bundled_scene_dir(path.name)
    raise SceneError(f"{path}: no such scene folder or scene file: not found here, nor among the bundled "
                     f"scenes ({', '.join(bundled_scene_names())})")


def _load_scene(path):
    path = find_scene(path)
    if path.suffix.lower() == ".xml" and not path.is_dir():     # Mitsuba 3's XML (FORMAT.md, "Mitsuba 3 XML")
        return _load_mitsuba(path)
    if path.is_dir():
        path = path / "scene.json"
    if not path.exists() and not path.is_symlink():
        raise SceneError(f"{path}: scene file not found")
    where = str(path)
    data = _read_json(path, where)
    camera = _parse_camera(where, data.get("camera"))
    materials_in = data.get("materials")
    if not isinstance(materials_in, dict) or not materials_in:
        _fail(where, "'materials' must be a non-empty object")
    materials = [_parse_material(where, name, m) for name, m in materials_in.items()]
    vertices, triangles, material_of, emission_of = _parse_shapes(where, path, data.get("shapes"),
                                                                  {m["name"]: i for i, m in enumerate(materials)})
    max_depth, rr_depth, clamp = _parse_integrator(where, data.get("integrator", {}))
    scene = Scene(
        name=path.parent.name, camera=camera,
        vertices=vertices, triangles=triangles, material_of=material_of, emission_of=emission_of,
        materials=materials,
        max_depth=max_depth, rr_depth=rr_depth, clamp=clamp,
        path=path, info={"notes": data.get("notes", "")})
    scene = drop_degenerate(scene, where)
    check_scene(scene, where)
    scene.reference, scene.reference_stderr, problem = _load_reference(path.parent, camera)
    scene.info.update(problem)
    return scene


def _load_mitsuba(path):
    """A Mitsuba 3 XML file's scene: mitsuba_scene.py's parts, checked as scene.json's are."""
    parts = read_mitsuba(path)
    where = parts["where"]
    materials = [_parse_material(mwhere, name, description) for mwhere, name, description in parts["materials"]]
    max_depth, rr_depth, _ = _parse_integrator(*parts["integrator"])
    scene = Scene(name=Path(where).stem, camera=Camera(**parts["camera"]), vertices=parts["vertices"],
                  triangles=parts["triangles"], material_of=parts["material_of"], emission_of=parts["emission_of"],
                  materials=materials, max_depth=max_depth, rr_depth=rr_depth, path=Path(where),
                  info={"notes": "read from Mitsuba 3 XML", **parts["info"]})
    scene = drop_degenerate(scene, where)
    check_scene(scene, where)
    check_clipping(scene, *parts["clips"])
    return scene


def _read_json(path, where):
    """scene.json's top-level object, its format and keys checked (a SceneError that names the problem)."""
    regular_file_inside(path, path.parent, "scene file", "scene.json.bytes")
    try:
        data = json.loads(path.read_text(encoding="utf-8"), object_pairs_hook=_no_duplicates)
    except json.JSONDecodeError as error:
        raise SceneError(f"{where}:{error.lineno}:{error.colno}: malformed JSON: {error.msg}") from None
    except (OSError, UnicodeDecodeError) as error:
        raise SceneError(f"{where}: cannot read the scene file: {error}") from None
    except SceneError as error:
        raise SceneError(f"{where}: {error}") from None
    except RecursionError:
        in_range("scene.json.depth", math.inf, f"{where}: JSON nesting depth")
    in_range("scene.json.depth", json_depth(data), f"{where}: JSON nesting depth")
    if not isinstance(data, dict):
        _fail(where, "top level must be a JSON object")
    if data.get("format") != FORMAT:
        _fail(where, f"'format' must be {FORMAT!r}, got {_short(data.get('format'))}")
    check_keys(where, data, TOP_KEYS, "the top level")
    return data


def _parse_shapes(where, path, shapes, index_of):
    """The shapes' meshes joined: (vertices, triangles, material of each triangle, emission of each)."""
    if not isinstance(shapes, list) or not shapes:
        _fail(where, "'shapes' must be a non-empty list")
    _start_big_build_early(path.parent, shapes)
    vertices, triangles, material_of, emission_of = [], [], [], []
    unmodelled = {}         # mesh file: what it holds that the toolkit does not model
    offset = 0
    for k, shape in enumerate(shapes):
        swhere = f"{where}: shapes[{k}]"
        if not isinstance(shape, dict) or "mesh" not in shape or "material" not in shape:
            _fail(swhere, "a shape needs 'mesh' and 'material'")
        check_keys(swhere, shape, SHAPE_KEYS, "a shape")
        if not isinstance(shape["mesh"], str) or not isinstance(shape["material"], str):
            _fail(swhere, "'mesh' (a path) and 'material' (a name) must be strings")
        if shape["material"] not in index_of:
            _fail(swhere, f"unknown material {shape['material']!r}")
        emission = _vector(f"{swhere}.emission", shape.get("emission", [0, 0, 0]), positive=True)
        for e in emission[emission > 0]:   # 0 turns a channel off; others must survive float32 products
            in_range("shape.emission", float(e), f"{swhere}.emission component")
        try:
            regular_file_inside(path.parent / shape["mesh"], path.parent, "mesh", "mesh.bytes")
            v, t, ignored = read_mesh(path.parent / shape["mesh"], offset, sum(len(x) for x in triangles))
            if "transform" in shape:     # absent: the file's numbers as they are, bit for bit
                matrix = checked(compose(operations_from_json(f"{swhere}.transform", shape["transform"])),
                                 f"{swhere} ({shape['mesh']})")
                v, t = place_mesh(matrix, v, t, f"{swhere} ({shape['mesh']})")
        except (ObjError, InputError) as error:
            raise SceneError(f"{swhere}: {error}" if not str(error).startswith(swhere) else str(error)) from None
        if ignored:
            unmodelled.setdefault(shape["mesh"], ignored)
        vertices.append(v)
        triangles.append(t + offset)
        offset += len(v)
        material_of.append(np.full(len(t), index_of[shape["material"]]))
        emission_of.append(np.repeat(emission[None], len(t), 0))
    if unmodelled:      # named once for the scene, not silently used and not once per triangle
        warnings.warn(f"{where}: ignored what the toolkit does not model: "
                      + "; ".join(f"{mesh}: {', '.join(things)}" for mesh, things in unmodelled.items()),
                      stacklevel=4)
    return (np.concatenate(vertices), np.concatenate(triangles), np.concatenate(material_of),
            np.concatenate(emission_of))


# Meshes of this many bytes or more make a scene whose BVH is likely built in a process of its own
# (toolkit/core/bvh.py, SEPARATE_FROM triangles: make_million.py's OBJ takes 42 bytes a triangle).
BUILD_EARLY_FROM_BYTES = 10 << 20


def _start_big_build_early(folder, shapes):
    """Start the BVH build's process of a big scene before its meshes are read: its start (about
    1.2 s of CPU: Python, numpy, numba's cached code) then runs on the second core while this one
    reads (build_process.start_early). Only the sizes of the files are looked at here; the loop
    that reads them says what is wrong with any."""
    size = 0
    for shape in shapes:
        try:
            size += regular_file_inside(folder / shape["mesh"], folder, "mesh", "mesh.bytes").stat().st_size
        except (TypeError, KeyError, InputError, OSError):
            pass
    if size >= BUILD_EARLY_FROM_BYTES:
        start_bvh_build_early()


def _parse_integrator(where, integrator):
    """(max_depth, rr_depth, clamp) of the scene's integrator settings."""
    integrator = _object(where, integrator, "'integrator'", INTEGRATOR_KEYS)
    max_depth = whole_number("integrator.max_depth", integrator.get("max_depth", -1), f"{where}: integrator.max_depth")
    rr_depth = whole_number("integrator.rr_depth", integrator.get("rr_depth", 5), f"{where}: integrator.rr_depth")
    clamp = integrator.get("clamp")     # absent or null: no clamping
    if clamp is not None:
        clamp = _number(f"{where}: integrator.clamp", clamp, "integrator.clamp")
    if max_depth < 0 and rr_depth < 0:
        _fail(where, "integrator: max_depth -1 (unbounded) needs Russian roulette (rr_depth >= 0); "
                     "without either, paths only end at each technique's own hard cap")
    return max_depth, rr_depth, clamp


def check_scene(scene, where=None):
    """What the device needs of a scene, however it was made (loaded, transformed, built in
    Python): lights, a triangle count and a scale within LIMITS. Raises SceneError."""
    where = where or f"scene {scene.name!r}"
    try:
        in_range("scene.triangles", len(scene.triangles), f"{where}: triangle count")
        if not len(scene.light_triangles):
            _fail(where, "the scene has no lights (no shape with a positive 'emission'): it would render black")
        lit = scene.emission_of[scene.emission_of > 0]
        for e in (lit.min(), lit.max()):
            in_range("shape.emission", float(e), f"{where}: emission component")
        lo, hi = scene.vertices.min(0), scene.vertices.max(0)
        extent = float(np.linalg.norm(hi - lo))
        in_range("scene.extent", extent, f"{where}: scene extent (bounding-box diagonal)")
        center = 0.5 * (lo + hi)
        in_range("scene.offset", float(np.linalg.norm(center)) / extent,
                 f"{where}: distance of the scene's centre from the origin, in extents,")
        in_range("camera.distance", float(np.linalg.norm(scene.camera.origin - center)) / extent,
                 f"{where}: camera distance from the scene's centre, in extents,")
        in_range("integrator.max_depth", scene.max_depth, f"{where}: integrator.max_depth")
        in_range("integrator.rr_depth", scene.rr_depth, f"{where}: integrator.rr_depth")
        if scene.clamp is not None:
            finite_number("integrator.clamp", scene.clamp, f"{where}: integrator.clamp")
    except SceneError:
        raise
    except InputError as error:
        raise SceneError(str(error)) from None


def drop_degenerate(scene, where="scene"):
    """Remove zero-area triangles with a warning (they have no normal and no light area)."""
    bad = _degenerate(scene.vertices, scene.triangles)
    if bad.all():
        _fail(where, "every triangle is degenerate (zero area)")
    if bad.any():
        warnings.warn(f"{where}: dropped {int(bad.sum())} degenerate (zero-area) triangle(s)", stacklevel=3)
        keep = ~bad
        scene = replace(scene, triangles=scene.triangles[keep], material_of=scene.material_of[keep],
                        emission_of=scene.emission_of[keep], dropped_triangles=int(bad.sum()))
    return scene


def _degenerate(vertices, triangles, block=1 << 16):
    """Which triangles have (nearly) zero area, measured a block of triangles at a time: a million
    at once made 250 MB of temporaries, whose freed memory the process then kept."""
    bad = np.empty(len(triangles), bool)
    for start in range(0, len(triangles), block):
        v = vertices[triangles[start:start + block]]
        cross = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        area2 = np.linalg.norm(cross, axis=1)
        edges = np.max([np.linalg.norm(v[:, i] - v[:, (i + 1) % 3], axis=1) for i in range(3)], axis=0)
        # Relative test: twice the area against the longest edge squared (a needle or a point).
        bad[start:start + block] = ~(area2 > 1e-12 * np.maximum(edges ** 2, 1e-300))
    return bad


def _load_reference(folder, camera):
    ref_path = folder / "reference.exr"
    if not ref_path.is_file():
        return None, None, {}
    info = {}

    def unusable(problem):
        warnings.warn(problem + "; renders are not compared with it", stacklevel=4)
        info["reference_problem"] = problem
        return None, None, info
    try:
        ref = read_exr(ref_path)
        err_path = folder / "reference_stderr.exr"
        err = read_exr(err_path) if err_path.is_file() else np.zeros_like(ref)
    except OSError as error:
        return unusable(f"reference cannot be read: {error}")
    if ref.shape[:2] != (camera.height, camera.width) or err.shape != ref.shape:
        return unusable(f"{ref_path}: size {ref.shape[1]}x{ref.shape[0]} differs from the camera "
                        f"({camera.width}x{camera.height}) or from reference_stderr.exr")
    if not (np.isfinite(ref).all() and np.isfinite(err).all()):
        return unusable(f"{ref_path}: NaN or infinite pixels")
    return ref, err, info


def bundled_scene_dir(name="cornell_box"):
    """Folder of a scene shipped with the toolkit (installed package or source checkout)."""
    return data_dir("toolkit.scenes", "scenes", f"{name}/scene.json") / name


def bundled_scene_names():
    """The names of the scenes shipped with the toolkit: the folders beside cornell_box's."""
    return sorted(p.parent.name for p in bundled_scene_dir().parent.glob("*/scene.json"))
