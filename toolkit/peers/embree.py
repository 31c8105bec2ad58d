"""Embree (through embreex) as the reference ray intersector.

Embree answers the same float32 question as our kernels: it is given the scene's triangles in
the device's rebased coordinates (vertices minus `DeviceScene.center`, subtracted in float64
and then rounded to float32) and the same float32 rays. Triangle indices are the scene's own
(`Scene.triangles` order), which is what `tris[i].prim` holds on the device.
"""
import numpy as np

from toolkit.core.layout import RAY_OFFSET_ULPS

NO_HIT = -1


class EmbreeMissing(OSError):
    """embreex is not installed (no wheels for this machine): the command says so, exit 2."""


def _center_of(scene):
    """The rebasing centre DeviceScene uses (midpoint of the vertex bounding box, float64)."""
    lo, hi = scene.vertices.min(0), scene.vertices.max(0)
    return 0.5 * (lo + hi)


def rebased_triangles(scene, center=None):
    """(M, 3, 3) float32 triangle vertices in the device's rebased coordinates."""
    center = _center_of(scene) if center is None else np.asarray(center, np.float64)
    local = np.asarray(scene.vertices, np.float64) - center          # float64 rebasing
    return np.ascontiguousarray(local[scene.triangles].astype(np.float32))


def _rays(origins, dirs):
    o = np.ascontiguousarray(np.asarray(origins)[:, :3], np.float32)
    d = np.ascontiguousarray(np.asarray(dirs)[:, :3], np.float32)
    if o.shape != d.shape:
        raise ValueError(f"origins {o.shape} and directions {d.shape} differ in shape")
    return o, d


class EmbreeIntersector:
    """Closest-hit and occlusion queries with Embree on the scene's rebased float32 triangles."""

    def __init__(self, scene, center=None):
        # Here, not at the top: embreex takes ~1 s to import, and only the cross-checks and the
        # ray benchmark use it (and `gpucheck` runs without it).
        try:
            from embreex import rtcore_scene
            from embreex.mesh_construction import TriangleMesh
        except ImportError as error:   # ARM Linux: no wheels, so setup.cfg does not ask for it there
            raise EmbreeMissing(f"Embree (the embreex package) cannot be imported ({error}): pip has it for "
                                "x86-64 and for macOS on Apple silicon; the Embree cross-check and the ray "
                                "benchmark need it") from None
        self.scene = scene
        self.center = _center_of(scene) if center is None else np.asarray(center, np.float64)
        self.triangles = rebased_triangles(scene, self.center)
        self._embree = rtcore_scene.EmbreeScene()
        self._mesh = TriangleMesh(self._embree, self.triangles)  # keep a reference

    def closest(self, origins, dirs):
        """(t, prim, u, v) of the closest hit in (0, inf); prim = -1 and t = inf on a miss.
        u, v are the barycentrics of the triangle's second and third vertex."""
        o, d = _rays(origins, dirs)
        if len(o) == 0:
            e = np.zeros(0, np.float32)
            return e, np.zeros(0, np.int32), e, e
        res = self._embree.run(o, d, dists=np.full(len(o), np.inf, np.float32), output=1)
        prim = np.asarray(res["primID"], np.int32).copy()
        miss = (prim < 0) | (np.asarray(res["geomID"]) < 0)
        prim[miss] = NO_HIT
        t = np.asarray(res["tfar"], np.float32).copy()
        u = np.asarray(res["u"], np.float32).copy()
        v = np.asarray(res["v"], np.float32).copy()
        t[miss] = np.inf
        u[miss] = 0.0
        v[miss] = 0.0
        return t, prim, u, v

    def occluded(self, origins, dirs, tmax):
        """Whether anything lies on each segment (0, tmax) (bool array)."""
        o, d = _rays(origins, dirs)
        if len(o) == 0:
            return np.zeros(0, bool)
        tmax = np.ascontiguousarray(np.broadcast_to(np.asarray(tmax, np.float32), (len(o),)))
        res = self._embree.run(o, d, dists=tmax.copy(), query="OCCLUDED")
        return np.asarray(res) >= 0


def camera_rays(device_scene, width, height):
    """Rays through the pixel centres of a width x height image, rows from the top, in the
    device's rebased coordinates: (origins (N, 3) float32, directions (N, 3) float32 unit).

    Directions follow scenes/FORMAT.md: normalize(f + (2x/w - 1) right + (1 - 2y/h) up), with
    the Camera record's float32 fields, evaluated in float64 and rounded once."""
    cam = device_scene.camera(width, height)
    origin = np.asarray(cam["origin"][:3], np.float64)
    f = np.asarray(cam["forward"][:3], np.float64)
    r = np.asarray(cam["right"][:3], np.float64)
    u = np.asarray(cam["up"][:3], np.float64)
    x = (np.arange(width) + 0.5)[None, :]
    y = (np.arange(height) + 0.5)[:, None]
    sx = np.broadcast_to(2.0 * x / width - 1.0, (height, width)).reshape(-1)
    sy = np.broadcast_to(1.0 - 2.0 * y / height, (height, width)).reshape(-1)
    d = f[None] + sx[:, None] * r[None] + sy[:, None] * u[None]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    origins = np.repeat(origin.astype(np.float32)[None], len(d), 0)
    return origins, d.astype(np.float32)


def uniform_directions(n, rng):
    """n unit vectors uniform on the sphere (normalised Gaussians), float64 (n, 3)."""
    d = rng.standard_normal((n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def random_rays(device_scene, n, rng, outside_fraction=0.5, outside_scale=3.0):
    """n rays in rebased coordinates: origins uniform in the scene's bounding box (and, for
    `outside_fraction` of them, in a box `outside_scale` times larger about the same centre),
    directions uniform on the sphere. Returns float32 (origins, dirs)."""
    lo = device_scene.scene.vertices.min(0) - device_scene.center
    hi = device_scene.scene.vertices.max(0) - device_scene.center
    n_out = int(round(n * outside_fraction))
    n_in = n - n_out
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    inside = lo + rng.random((n_in, 3)) * (hi - lo)
    outside = mid + (2.0 * rng.random((n_out, 3)) - 1.0) * half * outside_scale
    origins = np.concatenate([inside, outside])
    return origins.astype(np.float32), uniform_directions(n, rng).astype(np.float32)


def surface_points(device_scene, n, rng):
    """n uniform points of uniformly chosen triangles (so, on cornell_spheres, mostly of the dense
    sphere meshes), in rebased float64 coordinates: (triangle (n,), points (n, 3), unit normals (n, 3))."""
    scene = device_scene.scene
    triangle = rng.integers(len(scene.triangles), size=n)
    corners = (scene.vertices - device_scene.center)[scene.triangles[triangle]]
    a, b = rng.random((2, n, 1))
    flip = (a + b) > 1.0                                      # fold the square onto the triangle
    a, b = np.where(flip, 1.0 - a, a), np.where(flip, 1.0 - b, b)
    edge1, edge2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    normals = np.cross(edge1, edge2)
    return triangle, corners[:, 0] + a * edge1 + b * edge2, normals / np.linalg.norm(normals, axis=1, keepdims=True)


def surface_rays(device_scene, n, rng):
    """n rays that start on the scene's surfaces, as a path tracer's bounce and shadow rays do:
    origins from surface_points, directions uniform on the sphere, and each origin moved off its
    surface to its direction's side by the kernels' own offset (cl/scene.h: ray_offset).
    Rebased float32 (origins, dirs), as random_rays."""
    _, points, normals = surface_points(device_scene, n, rng)
    d = uniform_directions(n, rng)
    offset = (float(device_scene.epsilon)
              + np.abs(points).max(1, keepdims=True) * RAY_OFFSET_ULPS * np.finfo(np.float32).eps)
    side = np.where((normals * d).sum(1, keepdims=True) >= 0.0, 1.0, -1.0)
    return (points + side * offset * normals).astype(np.float32), d.astype(np.float32)
