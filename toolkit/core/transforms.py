"""Placing a shape or the camera with a transform: `translate`, `rotate`, `scale`, `matrix` and
`look_at`, composed in the order written, as Mitsuba 3 composes a `to_world` (scenes/FORMAT.md).

A transform is a list of operations, each a tuple: ("translate", xyz), ("rotate", axis, degrees),
("scale", xyz), ("matrix", 4x4), ("look_at", origin, target, up). scene.json's list of one-key
objects becomes such a list (`operations_from_json`); another scene format (Mitsuba's XML) can
build the same tuples and share `compose` and the rest. Each later operation is applied after the
earlier ones: M = T_n ... T_2 T_1, so [scale 2, translate x] scales first, then moves.

What a transform does to a mesh (`place_mesh`): points go through M. The face normal the toolkit
uses is the winding's, cross(v1 - v0, v2 - v0); for the affine map p -> A p + t that cross product
becomes det(A) A^-T n, the inverse-transpose normal a renderer must use under a non-uniform scale,
times the determinant's sign. So the normals stay right by themselves, except that a mirror
(det A < 0) turns them around: then each triangle is re-wound, so that a one-sided emitter still
emits on the side its transformed normal A^-T n points to.
"""
import math

import numpy as np

from toolkit.core.errors import InputError

# A 3x3 part whose smallest singular value is below this share of its largest flattens the
# shape (to float64's precision, after which float32 on the device has nothing left).
SINGULAR = 1e-12


def translate(xyz):
    m = np.eye(4)
    m[:3, 3] = xyz
    return m


def scale(xyz):
    """Per axis; a uniform scale s is (s, s, s)."""
    return np.diag([*np.broadcast_to(np.asarray(xyz, np.float64), (3,)), 1.0])


def rotate(axis, degrees):
    """Rotation by `degrees` about `axis` (any length), counter-clockwise when the axis points
    at the viewer (right-hand rule), as Mitsuba's rotate: Rodrigues' formula
    R = cos a I + sin a [k]x + (1 - cos a) k k^T."""
    k = np.asarray(axis, np.float64)
    k = k / np.linalg.norm(k)
    a = math.radians(degrees)
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    m = np.eye(4)
    m[:3, :3] = math.cos(a) * np.eye(3) + math.sin(a) * cross + (1 - math.cos(a)) * np.outer(k, k)
    return m


def look_at(origin, target, up):
    """Mitsuba's look_at: the local +z axis to the direction from `origin` to `target`, +y to
    `up` (made orthogonal), +x = up x z (the image's left), the local origin to `origin`."""
    origin, target, up = (np.asarray(v, np.float64) for v in (origin, target, up))
    z = (target - origin) / np.linalg.norm(target - origin)
    x = np.cross(up, z)
    x = x / np.linalg.norm(x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, np.cross(z, x), z, origin
    return m


MATRIX_OF = {"translate": translate, "scale": scale, "rotate": rotate, "matrix": np.asarray,
             "look_at": look_at}


def compose(operations):
    """The 4x4 matrix of a list of operations, the first applied first: T_n ... T_1."""
    m = np.eye(4)
    with np.errstate(over="ignore", invalid="ignore"):     # an overflow is refused by `checked`, in words
        for name, *values in operations:
            m = np.asarray(MATRIX_OF[name](*values), np.float64) @ m
    return m


def checked(m, where):
    """`m` if it is a finite affine map that keeps three dimensions; else an InputError naming
    `where` (the shape or the camera) and the problem."""
    if not np.all(np.isfinite(m)):
        raise InputError(f"{where}: the transform has a NaN or infinite entry")
    if not np.array_equal(m[3], [0.0, 0.0, 0.0, 1.0]):
        raise InputError(f"{where}: the transform's last row must be 0 0 0 1 (an affine map; a projection "
                         f"cannot place a shape), got {m[3].tolist()}")
    singular = np.linalg.svd(m[:3, :3], compute_uv=False)
    if not singular[-1] > SINGULAR * singular[0]:
        raise InputError(f"{where}: the transform is singular (determinant {np.linalg.det(m[:3, :3]):.3g}): "
                         "it flattens the shape onto a plane, a line or a point")
    return m


def place_mesh(m, vertices, triangles, where):
    """(vertices, triangles) moved by the checked matrix `m`: points through it, and the triangles
    re-wound (v0, v2, v1) where it mirrors, so each emits to the side of its transformed normal.
    A point that leaves float64's range is an InputError naming `where`."""
    # Written out, not `vertices @ A.T`: the same sums in the same order on every machine (a BLAS
    # may order them otherwise, and the image depends on every bit), and a quarter of the CPU time.
    with np.errstate(over="ignore", invalid="ignore"):     # refused below, in words
        moved = vertices[:, 0:1] * m[:3, 0] + vertices[:, 1:2] * m[:3, 1] + vertices[:, 2:3] * m[:3, 2] + m[:3, 3]
    if not np.all(np.isfinite(moved)):
        raise InputError(f"{where}: the transform takes a vertex outside the range of numbers (infinite)")
    if np.linalg.det(m[:3, :3]) < 0:
        triangles = triangles[:, [0, 2, 1]]
    return moved, triangles


def camera_frame(m, where):
    """(origin, target, up) of a camera placed by the checked matrix `m` (Mitsuba's sensor
    to_world: it looks along local +z, local +y up). A pinhole keeps its rays' angles only under
    rotation, translation and a uniform scale: anything else (a mirror, a shear, a scale per axis)
    is an InputError naming `where`."""
    a = m[:3, :3]
    gram = a.T @ a
    uniform = gram[0, 0]
    if np.linalg.det(a) < 0 or not np.allclose(gram, uniform * np.eye(3), rtol=0, atol=1e-9 * uniform):
        raise InputError(f"{where}: a camera's transform may only rotate, translate and scale uniformly "
                         "(a mirror, a shear or a per-axis scale would distort the pinhole's rays)")
    origin = m[:3, 3].copy()
    return origin, origin + a[:, 2], a[:, 1].copy()


# -- scene.json's spelling: a list of one-key objects ------------------------------------------

JSON_FORMS = {"translate": "[x, y, z]", "scale": "s or [x, y, z]",
              "rotate": '{"axis": [x, y, z], "angle_deg": a}', "matrix": "4 rows of 4 numbers",
              "look_at": '{"origin": [x, y, z], "target": [x, y, z], "up": [x, y, z]}'}


def operations_from_json(where, value):
    """scene.json's "transform" list as operations for `compose`; an InputError naming the entry."""
    if not isinstance(value, list) or not value:
        raise InputError(f"{where}: a transform is a non-empty list of operations, each one of: "
                         + "; ".join(f'{{"{k}": {v}}}' for k, v in JSON_FORMS.items()))
    return [_operation(f"{where}[{i}]", entry) for i, entry in enumerate(value)]


def _operation(where, entry):
    if not isinstance(entry, dict) or len(entry) != 1 or next(iter(entry)) not in JSON_FORMS:
        raise InputError(f"{where}: expected one of {', '.join(JSON_FORMS)} as the only key, got {_short(entry)}")
    (name, value), = entry.items()
    where = f"{where}.{name}"
    if name == "translate":
        return name, _numbers(where, value, 3)
    if name == "scale":
        return name, _numbers(where, [value] * 3 if _is_number(value) else value, 3)
    if name == "matrix":
        if not isinstance(value, list) or len(value) != 4:
            raise InputError(f"{where}: expected 4 rows of 4 numbers, got {_short(value)}")
        return name, np.array([_numbers(f"{where}[{r}]", row, 4) for r, row in enumerate(value)])
    fields = {"rotate": ("axis", "angle_deg"), "look_at": ("origin", "target", "up")}[name]
    if not isinstance(value, dict) or set(value) != set(fields):
        raise InputError(f"{where}: expected {JSON_FORMS[name]}, got {_short(value)}")
    if name == "rotate":
        axis = _numbers(f"{where}.axis", value["axis"], 3)
        if not np.any(axis):
            raise InputError(f"{where}.axis: the axis of a rotation cannot be 0 0 0")
        return name, axis, _numbers(f"{where}.angle_deg", [value["angle_deg"]], 1)[0]
    origin, target, up = (_numbers(f"{where}.{k}", value[k], 3) for k in fields)
    forward = target - origin
    sideways = np.linalg.norm(np.cross(forward, up))
    if not np.any(forward) or not sideways > 1e-9 * np.linalg.norm(forward) * np.linalg.norm(up):
        raise InputError(f"{where}: target equals origin, or up is parallel to the viewing direction")
    return name, origin, target, up


def _is_number(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _numbers(where, value, n):
    if not isinstance(value, list) or len(value) != n or not all(_is_number(x) for x in value):
        raise InputError(f"{where}: expected {n} numbers, got {_short(value)}")
    try:
        v = np.array(value, np.float64)
    except OverflowError:       # an integer beyond float64
        v = np.array([math.inf])
    if not np.all(np.isfinite(v)):
        raise InputError(f"{where}: NaN or infinite value in {_short(value)}")
    return v


def _short(value, n=60):
    text = repr(value)
    return text if len(text) <= n else text[:n] + "..."
