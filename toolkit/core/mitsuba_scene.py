"""A Mitsuba 3 XML scene as the parts of a toolkit Scene: the subset the toolkit models
(scenes/FORMAT.md, "Mitsuba 3 XML"), the inverse of the writer in toolkit/peers/mitsuba.py.
scene.py's load_scene builds and checks the Scene from them, as it does for scene.json.

mitsuba_xml.py reads the files into Nodes (includes, defaults and parameters done); here each
element is mapped to what the toolkit models, or refused: an element or a property outside the
subset stops the load with an InputError naming it, its file:line and what is supported, rather
than render a different scene than Mitsuba would.
"""
import math
import re
import warnings

import numpy as np

from toolkit.core.analytic_shapes import SHAPES as ANALYTIC_SHAPES
from toolkit.core.errors import InputError
from toolkit.core.mesh_files import read_mesh
from toolkit.core.mitsuba_xml import read_xml
from toolkit.core.obj import ObjError
from toolkit.core.transforms import camera_frame, checked, compose, place_mesh
from toolkit.core.validate import LIMITS, finite_number, in_range, whole_number

SUPPORTED = {
    "shape": ("obj", "ply", "rectangle", "cube", "disk", "sphere"),
    "bsdf": ("diffuse", "conductor", "roughconductor", "dielectric", "twosided"),
    "emitter": ("area",),
    "sensor": ("perspective",),
    "film": ("hdrfilm",),
    "integrator": ("path", "bdpt", "ptracer"),
}
# The elements the toolkit reads; any other (texture, medium, spectrum, volume, ...) is refused.
OBJECT_TAGS = ("shape", "bsdf", "emitter", "sensor", "film", "rfilter", "sampler", "integrator")
PROPERTY_TAGS = ("integer", "float", "boolean", "string", "rgb", "point", "vector", "transform")
SUBSET = ("shapes " + ", ".join(SUPPORTED["shape"]) + "; bsdfs " + ", ".join(SUPPORTED["bsdf"])
          + "; area emitters; a perspective sensor with an hdrfilm; the path, bdpt and ptracer integrators' depths; "
          "rgb and float colours; default, ref and include (scenes/FORMAT.md, 'Mitsuba 3 XML')")
# Mitsuba's defaults where a property is absent.
FILM_SIZE = (768, 576)
NEAR_CLIP, FAR_CLIP = 1e-2, 1e4
AIR_IOR = 1.000277


def unsupported(node, what=None):
    return InputError(f"{node.where}: {what or node.describe()} is not in the subset of Mitsuba 3 the toolkit "
                      f"models. Supported: {SUBSET}")


def _numbers(node, text, n=None):
    try:
        values = [float(x) for x in re.split(r"[,\s]+", text.strip())] if text.strip() else []
    except ValueError:
        raise InputError(f"{node.where}: expected numbers in {node.describe()}, got {text[:60]!r}") from None
    if n is not None and len(values) not in ((1, n) if n == 3 and node.tag == "rgb" else (n,)):
        raise InputError(f"{node.where}: expected {n} numbers in {node.describe()}, got {text[:60]!r}")
    if not all(math.isfinite(v) for v in values):
        raise InputError(f"{node.where}: NaN or infinite value in {node.describe()}")
    return values


def _attr(node, key):
    if key not in node.attrib:
        raise InputError(f"{node.where}: {node.describe()} needs a '{key}' attribute")
    return node.attrib[key]


def _xyz(node, default):
    """A point or vector: value="x, y, z", or x= y= z= attributes (each absent one: default)."""
    if "value" in node.attrib:
        return np.array(_numbers(node, node.attrib["value"], 3))
    return np.array([_numbers(node, node.attrib.get(k, str(default)), 1)[0] for k in "xyz"])


def _transform(node):
    """Mitsuba's transform operations as toolkit/core/transforms.py's tuples, in the order written."""
    operations = []
    for op in node.children:
        if op.children:
            raise unsupported(op.children[0])
        if op.tag == "translate":
            operations.append(("translate", _xyz(op, 0.0)))
        elif op.tag == "scale":
            value = op.attrib.get("value")
            if value is not None and len(_numbers(op, value)) == 1:
                operations.append(("scale", np.full(3, _numbers(op, value)[0])))
            else:
                operations.append(("scale", _xyz(op, 1.0)))
        elif op.tag == "rotate":
            axis = _xyz(op, 0.0)
            if not axis.any():
                raise InputError(f"{op.where}: <rotate> needs a non-zero axis (value=\"x, y, z\" or x= y= z=)")
            operations.append(("rotate", axis, _numbers(op, _attr(op, "angle"), 1)[0]))
        elif op.tag == "matrix":
            operations.append(("matrix", np.array(_numbers(op, _attr(op, "value"), 16)).reshape(4, 4)))
        elif op.tag == "lookat":
            origin, target = (np.array(_numbers(op, _attr(op, k), 3)) for k in ("origin", "target"))
            up = np.array(_numbers(op, op.attrib.get("up", "0, 1, 0"), 3))
            forward = target - origin
            if not forward.any() or not np.linalg.norm(np.cross(forward, up)) > 1e-9 * np.linalg.norm(forward) * \
                    np.linalg.norm(up):
                raise InputError(f"{op.where}: <lookat>: target equals origin, or up is parallel to the view")
            operations.append(("look_at", origin, target, up))
        else:
            raise unsupported(op, f"<{op.tag}> in a transform (translate, rotate, scale, matrix, lookat are)")
    return checked(compose(operations), f"{node.where}: {node.describe()}")


class Plugin:
    """One object element (<shape>, <bsdf>, ...): its properties by name, its child objects,
    each property checked against the ones this plugin models."""

    def __init__(self, node, known, ids):
        self.node, self.type, self.props, self.objects = node, node.attrib.get("type"), {}, []
        for child in node.children:
            if child.tag == "ref":
                target = ids.get(child.attrib.get("id"))
                if target is None:
                    raise InputError(f"{child.where}: <ref id={child.attrib.get('id')!r}> names no element")
                self.objects.append(target)
            elif child.tag in OBJECT_TAGS:
                self.objects.append(child)
            elif child.tag in PROPERTY_TAGS:
                name = _attr(child, "name")
                if name not in known:
                    raise unsupported(child, f"property '{name}' of {node.describe()}"
                                             + (f" (modelled: {', '.join(sorted(known))})" if known else ""))
                if name in self.props:
                    raise InputError(f"{child.where}: property '{name}' given twice in {node.describe()}")
                self.props[name] = child
            else:
                raise unsupported(child)

    def get(self, name, default=None):
        return self.props.get(name, default)

    def number(self, name, default):
        p = self.props.get(name)
        if p is None:
            return default
        if p.tag not in ("float", "integer"):
            raise unsupported(p, f"<{p.tag} name='{name}'> (a number is expected)")
        return _numbers(p, _attr(p, "value"), 1)[0]

    def integer(self, name, default):
        value = self.number(name, default)
        if value != int(value):
            raise InputError(f"{self.props[name].where}: '{name}' must be a whole number, got {value}")
        return int(value)

    def string(self, name, default):
        p = self.props.get(name)
        return default if p is None else _attr(p, "value")

    def boolean(self, name, default):
        p = self.props.get(name)
        if p is None:
            return default
        value = _attr(p, "value").strip().lower()
        if value not in ("true", "false"):
            raise InputError(f"{p.where}: '{name}' must be true or false, got {value!r}")
        return value == "true"

    def colour(self, name, default):
        """An rgb or a float (grey) colour; a texture or a spectrum is refused."""
        p = self.props.get(name)
        if p is None:
            return np.full(3, default, np.float64)
        if p.tag not in ("rgb", "float"):
            raise unsupported(p, f"<{p.tag} name='{name}'> (colours are rgb or float here)")
        values = _numbers(p, _attr(p, "value"), 3 if p.tag == "rgb" else 1)
        return np.broadcast_to(np.array(values, np.float64), (3,)).copy()

    def transform(self, name):
        p = self.props.get(name)
        if p is None:
            return np.eye(4)
        if p.tag != "transform":
            raise unsupported(p, f"<{p.tag} name='{name}'> (a <transform> is expected)")
        return _transform(p)

    def children(self, tag):
        return [o for o in self.objects if o.tag == tag]

    def only(self, tag):
        found = self.children(tag)
        if len(found) > 1:
            raise InputError(f"{found[1].where}: {self.node.describe()} has more than one <{tag}>")
        return found[0] if found else None


def _check_type(node, tag):
    if node.tag != tag:
        raise unsupported(node, f"<{node.tag}> where a <{tag}> is expected")
    if node.attrib.get("type") not in SUPPORTED[tag]:
        raise unsupported(node)


class _Builder:
    """The walk over the scene's elements; collects the triangles, materials and camera."""

    def __init__(self, root, reader):
        self.reader, self.where = reader, str(reader.main)
        self.ids = {}
        self._collect_ids(root)
        self.materials, self.material_index = [], {}      # one material per <bsdf> element
        self.vertices, self.triangles, self.material_of, self.emission_of = [], [], [], []
        self.n_vertices = self.n_triangles = 0
        self.one_sided, self.smooth, self.unmodelled, self.info = [], [], {}, {}

    def _collect_ids(self, node):
        for child in node.children:
            if "id" in child.attrib and child.tag in OBJECT_TAGS:
                if child.attrib["id"] in self.ids:
                    raise InputError(f"{child.where}: id {child.attrib['id']!r} is used twice (first at "
                                     f"{self.ids[child.attrib['id']].where})")
                self.ids[child.attrib["id"]] = child
            self._collect_ids(child)

    def build(self, root):
        """The scene's parts: scene.py's MitsubaParts."""
        sensor = integrator = None
        for node in root.children:
            if node.tag == "sensor":
                if sensor is not None:
                    raise InputError(f"{node.where}: a second <sensor> (the toolkit renders one camera)")
                sensor = node
            elif node.tag == "integrator":
                integrator = node
            elif node.tag == "shape":
                self.shape(node)
            elif node.tag in ("bsdf", "emitter") and "id" in node.attrib:
                _check_type(node, node.tag)     # a definition for a shape's <ref>, refused early if unmodelled
            elif node.tag == "path":            # a folder Mitsuba searches for files: not followed here
                warnings.warn(f"{node.where}: <path> ignored: filenames are found from the main file's folder "
                              "only", stacklevel=4)
            elif node.tag == "emitter":
                if node.attrib.get("type") in SUPPORTED["emitter"]:
                    raise InputError(f"{node.where}: an area emitter must be inside a <shape> (or referenced by one)")
                raise unsupported(node)
            elif node.tag == "bsdf":
                warnings.warn(f"{node.where}: {node.describe()} has no id and no shape: unused", stacklevel=4)
            else:
                raise unsupported(node)
        if not self.triangles:
            raise InputError(f"{self.where}: the scene has no <shape>")
        if sensor is None:
            raise InputError(f"{self.where}: the scene has no <sensor> (the toolkit needs a perspective camera)")
        vertices, triangles = np.concatenate(self.vertices), np.concatenate(self.triangles)
        camera, clips = self.sensor(sensor)
        integrator = self.integrator(integrator)
        if self.one_sided:
            warnings.warn(f"{self.one_sided[0]}: {len(self.one_sided)} one-sided bsdf(s) (not in a <twosided>): in "
                          "Mitsuba their back is black; the toolkit's surfaces reflect on both sides, so the images "
                          "agree where no back face is seen or lit", stacklevel=4)
        if self.smooth:
            warnings.warn(f"{'; '.join(self.smooth)}: Mitsuba shades these meshes with normals interpolated between "
                          "their faces (face_normals is false); the toolkit uses each face's own normal, so the "
                          "images differ where they curve: write <boolean name=\"face_normals\" value=\"true\"/>",
                          stacklevel=4)
        if self.unmodelled:
            warnings.warn(f"{self.where}: ignored what the toolkit does not model: " + "; ".join(
                f"{mesh}: {', '.join(things)}" for mesh, things in self.unmodelled.items()), stacklevel=4)
        return {"where": self.where, "camera": camera, "clips": clips, "vertices": vertices, "triangles": triangles,
                "material_of": np.concatenate(self.material_of), "emission_of": np.concatenate(self.emission_of),
                "materials": self.materials, "integrator": integrator, "info": self.info}

    # -- shapes ------------------------------------------------------------------------------

    def shape(self, node):
        _check_type(node, "shape")
        kind = node.attrib["type"]
        known = {"to_world", "flip_normals", "face_normals"} | \
            ({"filename"} if kind in ("obj", "ply") else set()) | ({"center", "radius"} if kind == "sphere" else set())
        p = Plugin(node, known, self.ids)
        for other in p.objects:
            if other.tag not in ("bsdf", "emitter"):
                raise unsupported(other, f"<{other.tag}> inside a <shape>")
        where = f"{node.where}: {node.describe()}"
        material = self.material(p.only("bsdf"), node)      # before the mesh: a refusal names the element first
        emission = self.emission(p.only("emitter"))
        if kind in ("obj", "ply"):
            path = self.reader.resolve(node, p.string("filename", None), "mesh", "mesh.bytes")
            if path.suffix.lower() != f".{kind}":
                raise InputError(f"{where}: the file {path.name} is not a .{kind} file")
            try:
                v, t, ignored = read_mesh(path, self.n_vertices, self.n_triangles)
            except (ObjError, InputError) as error:
                raise InputError(f"{where}: {error}") from None
            if ignored:
                self.unmodelled.setdefault(path.name, ignored)
            if not p.boolean("face_normals", False) and not _flat_at_every_vertex(v, t):
                self.smooth.append(f"{node.where} ({path.name})")
        else:
            v, t = ANALYTIC_SHAPES[kind]()
        matrix = p.transform("to_world")
        if kind == "sphere":          # Mitsuba: to_world * translate(center) * scale(radius)
            radius = p.number("radius", 1.0)
            center = _xyz(p.get("center"), 0.0) if p.get("center") is not None else np.zeros(3)
            matrix = checked(matrix @ compose([("scale", np.full(3, radius)), ("translate", center)]), where)
        v, t = place_mesh(matrix, v, t, where)
        if p.boolean("flip_normals", False):
            t = t[:, [0, 2, 1]]
        in_range("scene.vertices", self.n_vertices + len(v), f"{where}: vertices of all shapes")
        in_range("scene.triangles", self.n_triangles + len(t), f"{where}: triangles of all shapes")
        self.vertices.append(v)
        self.triangles.append(t + self.n_vertices)
        self.material_of.append(np.full(len(t), material))
        self.emission_of.append(np.repeat(emission[None], len(t), 0))
        self.n_vertices += len(v)
        self.n_triangles += len(t)

    def emission(self, node):
        if node is None:
            return np.zeros(3)
        _check_type(node, "emitter")
        radiance = Plugin(node, {"radiance"}, self.ids)
        if radiance.get("radiance") is None:
            raise InputError(f"{node.where}: an area emitter needs a 'radiance'")
        value = radiance.colour("radiance", 0.0)
        if np.any(value < 0):
            raise InputError(f"{node.where}: negative radiance")
        for e in value[value > 0]:
            in_range("shape.emission", float(e), f"{node.where}: radiance component")
        return value

    # -- materials ---------------------------------------------------------------------------

    def material(self, node, shape):
        """The index of the material of a <bsdf> element (Mitsuba's default: diffuse 0.5)."""
        key = id(node)
        if key not in self.material_index:
            if node is None:
                description, name = {"type": "diffuse", "reflectance": [0.5] * 3}, "default_diffuse"
                self.one_sided.append(shape.where)
            else:
                description = self.bsdf(node)
                name = node.attrib.get("id") or f"{node.attrib['type']}_{len(self.materials)}"
            self.material_index[key] = len(self.materials)     # (where, name, scene.json's description)
            listed = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in description.items()}
            self.materials.append((node.where if node is not None else shape.where, name, listed))
        return self.material_index[key]

    def bsdf(self, node, two_sided=False):
        """A scene.json material description of a <bsdf>."""
        _check_type(node, "bsdf")
        kind = node.attrib["type"]
        if kind == "twosided":
            if two_sided:
                raise InputError(f"{node.where}: a <twosided> inside a <twosided>")
            p = Plugin(node, set(), self.ids)
            inner = p.children("bsdf")
            if len(inner) != 1 or len(p.objects) != 1:
                raise unsupported(node, "a <twosided> with other than one <bsdf> (a different back is not "
                                        "modelled)")
            if inner[0].attrib.get("type") == "dielectric":
                raise InputError(f"{inner[0].where}: a dielectric cannot be two-sided (Mitsuba refuses it too)")
            return self.bsdf(inner[0], two_sided=True)
        if kind != "dielectric" and not two_sided:
            self.one_sided.append(node.where)
        if kind == "diffuse":
            p = Plugin(node, {"reflectance"}, self.ids)
            return {"type": "diffuse", "reflectance": p.colour("reflectance", 0.5)}
        if kind in ("conductor", "roughconductor"):
            # No Fresnel: only Mitsuba's material "none" (reflectance 1 at every angle, times
            # specular_reflectance) is what the toolkit's mirror and glossy compute.
            rough = kind == "roughconductor"
            known = {"material", "specular_reflectance"} | ({"distribution", "alpha", "sample_visible"} if rough else set())
            p = Plugin(node, known, self.ids)
            if p.string("material", "none") != "none":
                raise unsupported(p.get("material"), f"material '{p.string('material', '')}' of {node.describe()} "
                                  "(a conductor's Fresnel term is not modelled: use material \"none\")")
            reflectance = p.colour("specular_reflectance", 1.0)
            if not rough:
                return {"type": "mirror", "reflectance": reflectance}
            if p.string("distribution", "beckmann") != "ggx":
                raise unsupported(p.get("distribution") or node, f"{node.describe()}'s distribution "
                                  f"'{p.string('distribution', 'beckmann')}' (Mitsuba's default is beckmann; "
                                  "the toolkit's glossy is GGX: write <string name=\"distribution\" value=\"ggx\"/>)")
            return {"type": "glossy", "reflectance": reflectance, "alpha": p.number("alpha", 0.1)}
        # dielectric: the toolkit's exterior has index 1, so ext_ior must be 1
        p = Plugin(node, {"int_ior", "ext_ior"}, self.ids)
        ext = p.number("ext_ior", AIR_IOR)
        if ext != 1.0:
            raise InputError(f"{p.get('ext_ior').where if p.get('ext_ior') else node.where}: {node.describe()}'s "
                             f"ext_ior is {ext} (Mitsuba's default is air, {AIR_IOR}); the toolkit's exterior is "
                             "index 1: write <float name=\"ext_ior\" value=\"1\"/>")
        return {"type": "dielectric", "ior": p.number("int_ior", 1.5046)}

    # -- camera and integrator ---------------------------------------------------------------

    def sensor(self, node):
        _check_type(node, "sensor")
        p = Plugin(node, {"fov", "fov_axis", "near_clip", "far_clip", "to_world", "focus_distance"}, self.ids)
        if p.get("fov") is None:
            raise InputError(f"{node.where}: the perspective sensor needs a 'fov' (focal_length is not modelled)")
        if p.get("focus_distance") is not None:
            warnings.warn(f"{p.get('focus_distance').where}: focus_distance ignored (a pinhole camera, as "
                          "Mitsuba's perspective sensor, is sharp at every distance)", stacklevel=5)
        for other in p.objects:
            if other.tag not in ("film", "sampler"):
                raise unsupported(other, f"<{other.tag}> inside a <sensor>")
        film = p.only("film")
        width, height = self.film(film) if film is not None else FILM_SIZE
        sampler = p.only("sampler")
        if sampler is not None:
            self.info["spp"] = Plugin(sampler, {"sample_count", "seed"}, self.ids).integer("sample_count", 4)
        fov = p.number("fov", None)
        axis = p.string("fov_axis", "x")
        if axis in ("smaller", "larger"):
            axis = "x" if (width <= height) == (axis == "smaller") else "y"
        elif axis == "diagonal":     # the same camera, its field of view given along x
            fov = math.degrees(2 * math.atan(math.tan(math.radians(fov) / 2) * width / math.hypot(width, height)))
            axis = "x"
        elif axis not in ("x", "y"):
            raise InputError(f"{p.get('fov_axis').where}: fov_axis must be x, y, diagonal, smaller or larger, "
                             f"got {axis!r}")
        where = f"{node.where}: the perspective sensor"
        origin, target, up = camera_frame(p.transform("to_world"), f"{where}'s to_world")
        camera = dict(origin=origin, target=target, up=up, fov_axis=axis,
                      fov_deg=finite_number("camera.fov_deg", fov, f"{where}'s fov"),
                      width=whole_number("camera.width", width, f"{where}'s film width"),
                      height=whole_number("camera.height", height, f"{where}'s film height"))
        return camera, (p.number("near_clip", NEAR_CLIP), p.number("far_clip", FAR_CLIP), node.where)

    def film(self, node):
        _check_type(node, "film")
        p = Plugin(node, {"width", "height", "pixel_format", "component_format"}, self.ids)
        if p.string("pixel_format", "rgb") not in ("rgb", "rgba"):
            raise unsupported(p.get("pixel_format"), f"pixel_format '{p.string('pixel_format', '')}' (rgb is)")
        for other in p.objects:
            if other.tag != "rfilter":
                raise unsupported(other, f"<{other.tag}> inside a <film>")
            if other.attrib.get("type") != "box":
                warnings.warn(f"{other.where}: rfilter '{other.attrib.get('type')}' replaced by the toolkit's "
                              "box filter (one pixel wide): the image is a little sharper than Mitsuba's",
                              stacklevel=5)
            elif other.children:
                raise unsupported(other.children[0], f"a property of the box filter (it has none)")
        return p.integer("width", FILM_SIZE[0]), p.integer("height", FILM_SIZE[1])

    def integrator(self, node):
        if node is None:        # Mitsuba's default: path, unbounded, roulette from depth 5
            return self.where, {"max_depth": -1, "rr_depth": 5}
        if node.attrib.get("type") not in SUPPORTED["integrator"]:
            raise unsupported(node)
        p = Plugin(node, {"max_depth", "rr_depth", "hide_emitters"}, self.ids)
        if p.boolean("hide_emitters", False):
            raise unsupported(p.get("hide_emitters"), "hide_emitters = true (the toolkit shows emitters)")
        max_depth, rr_depth = p.integer("max_depth", -1), p.integer("rr_depth", 5)
        if rr_depth > LIMITS["integrator.rr_depth"][1] and 0 <= max_depth <= rr_depth:
            rr_depth = -1        # roulette from a depth no path reaches: none, in the toolkit's words
        return f"{node.where}: {node.describe()}", {"max_depth": max_depth, "rr_depth": rr_depth}


def _flat_at_every_vertex(vertices, triangles):
    """Whether every vertex's faces share one normal: then Mitsuba's interpolated vertex normals
    (computed, or read from the file) are the face normals the toolkit uses."""
    v = vertices[triangles]
    normals = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1), 1e-300)[:, None]
    total, count = np.zeros_like(vertices), np.zeros(len(vertices))
    for corner in range(3):
        np.add.at(total, triangles[:, corner], normals)
        np.add.at(count, triangles[:, corner], 1)
    used = count > 0
    return bool(np.all(np.linalg.norm(total[used], axis=1) >= count[used] * (1 - 1e-9)))


def _distance(point, triangle):
    """The distance from `point` to a triangle (3x3): to its plane where the foot lies inside it,
    else to its nearest edge."""
    a, b, c = triangle
    n = np.cross(b - a, c - a)
    foot = point - np.dot(point - a, n) / np.dot(n, n) * n
    if all(np.dot(np.cross(q - p, foot - p), n) >= 0 for p, q in ((a, b), (b, c), (c, a))):
        return float(np.linalg.norm(point - foot))

    def to_edge(p, q):
        s = np.clip(np.dot(point - p, q - p) / np.dot(q - p, q - p), 0.0, 1.0)
        return np.linalg.norm(point - (p + s * (q - p)))
    return float(min(to_edge(a, b), to_edge(b, c), to_edge(c, a)))


def check_clipping(scene, near, far, where):
    """Mitsuba's clipping planes are allowed only where they clip nothing the camera sees: no
    triangle comes nearer to the camera than the near plane can reach into the view (the ball
    through the near plane's corners), and no vertex lies beyond the far plane."""
    cam = scene.camera
    forward, right, up = cam.basis()
    reach = near * math.sqrt(1 + np.dot(right, right) + np.dot(up, up))      # to the near plane's corners
    v = scene.vertices[scene.triangles]
    centre = v.mean(1)
    radius = np.linalg.norm(v - centre[:, None], axis=2).max(1)
    near_ones = np.linalg.norm(centre - cam.origin, axis=1) - radius < reach
    near_ones[near_ones] = [_distance(cam.origin, tri) < reach for tri in v[near_ones]]    # the few: exactly
    if near <= 0 or near_ones.any():
        raise InputError(f"{where}: near_clip {near:g} may clip triangles that the toolkit would show (it has no "
                         f"near plane): {int(near_ones.sum())} come within {reach:g} of the camera; lower near_clip")
    depth = (scene.vertices - cam.origin) @ forward
    if not far > near or (depth > far).any():
        raise InputError(f"{where}: far_clip {far:g} clips the scene (its farthest vertex is at depth "
                         f"{depth.max():g}); the toolkit has no far plane: raise far_clip")


def read_mitsuba(path):
    """The parts of the Scene of a Mitsuba 3 XML file (a dict: see _Builder.build); an InputError
    naming the file, line and problem."""
    root, reader = read_xml(path)
    return _Builder(root, reader).build(root)
