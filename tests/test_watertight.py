"""No ray slips between triangles that share an edge or a vertex (issue 14, item 6).

cl/bvh.h's ray/triangle test is watertight (Woop, Benthin and Wald 2013): two triangles that
share an edge evaluate its edge function from the same numbers with opposite signs, so a ray
through the edge hits one of them. That needs the test's arithmetic without fused multiply-add
(`#pragma OPENCL FP_CONTRACT OFF` in its body, and in the wide BVH's four-lane copy). The rays
here are aimed exactly at shared edges and shared vertices, from many directions (grazing ones
too), through both BVHs:
- the Cornell box's quads, each split in two triangles along a diagonal: points on the diagonals;
- a fan of triangles around a vertex, in a tilted plane with coordinates that are not round
  numbers: the shared vertex itself, and points on the spokes (the shared edges).
"""
from dataclasses import replace

import numpy as np
import pytest

from toolkit.opencl.device_scene import DeviceScene
from toolkit.opencl.raycast import DeviceRaycaster

BVHS = ("binary", "wide")


def _unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _directions(normal, rng, n_random=24):
    """Unit directions that cross a plane of this normal (from both sides): along the normal,
    along the axes, tilted, and random ones down to grazing (|cos| = 0.02)."""
    normal = _unit(normal)
    axes = np.concatenate([np.eye(3), -np.eye(3)])
    dirs = [normal, -normal] + [a for a in axes if abs(a @ normal) > 0.02]
    tangent = _unit(np.cross(normal, [0.3, 0.5, 0.7]))
    for cos in (0.9, 0.5, 0.1, 0.02):
        sin = np.sqrt(1 - cos * cos)
        for sign in (1, -1):
            dirs.append(sign * cos * normal + sin * tangent)
            dirs.append(sign * cos * normal - sin * np.cross(normal, tangent))
    random = _unit(rng.normal(size=(n_random, 3)))
    random = random[np.abs(random @ normal) > 0.02]
    return _unit(np.concatenate([np.array(dirs), random]))


def _rays(targets, normal, distance, rng):
    """Origins and directions (float32, device coordinates) of rays that reach each target
    (device coordinates, float64) after `distance`, one ray per target and direction."""
    dirs = _directions(normal, rng)
    t = np.repeat(targets, len(dirs), axis=0)
    d = np.tile(dirs, (len(targets), 1))
    return (t - distance * d).astype(np.float32), d.astype(np.float32)


def _cast(queue, scene, origins, dirs):
    return {bvh: DeviceRaycaster(queue, DeviceScene(queue, scene, bvh=bvh)).closest(origins, dirs) for bvh in BVHS}


def _shared_diagonals(scene):
    """(i, j, a, b): triangles i and j that lie in one plane and share the edge a-b (world
    coordinates): a quad's two halves."""
    v = scene.vertices[scene.triangles]                      # (M, 3 corners, 3)
    normals = _unit(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]))
    keys = [[tuple(p) for p in tri] for tri in v]
    edges = {}
    for i, corners in enumerate(keys):
        for k in range(3):
            edge = frozenset((corners[k], corners[(k + 1) % 3]))
            edges.setdefault(edge, []).append(i)
    pairs = []
    for edge, tris in edges.items():
        if len(tris) == 2 and abs(normals[tris[0]] @ normals[tris[1]]) > 1 - 1e-9:
            a, b = (np.array(p) for p in edge)
            pairs.append((tris[0], tris[1], a, b))
    return pairs, normals


def test_no_ray_slips_through_the_diagonal_of_a_quad(queue, cornell_box):
    scene = cornell_box
    pairs, normals = _shared_diagonals(scene)
    assert len(pairs) >= 15, "the Cornell box is made of quads split in two triangles"
    center = DeviceScene(queue, scene, bvh="binary").center
    distance = 0.02 * scene.extent     # close: nothing else lies between the origin and the quad
    rng = np.random.default_rng(14)
    origins, dirs, expected = [], [], []
    for i, j, a, b in pairs:
        s = np.concatenate([[0.5, 1 / 3, 2 / 3, 1e-3, 1 - 1e-3], rng.random(11)])
        targets = (a + s[:, None] * (b - a)) - center          # device coordinates, float64
        o, d = _rays(targets, normals[i], distance, rng)
        origins.append(o), dirs.append(d), expected.append(np.tile([i, j], (len(o), 1)))
    origins, dirs, expected = np.concatenate(origins), np.concatenate(dirs), np.concatenate(expected)
    for bvh, (t, prim, _, _) in _cast(queue, scene, origins, dirs).items():
        on_pair = (prim == expected[:, 0]) | (prim == expected[:, 1])
        # Anything else hit must lie in front of the quad (a box standing on the floor) or in its
        # plane at the same t (the small box's bottom lies on the floor: the lower index wins).
        slipped = ~on_pair & ((prim < 0) | (t > distance * (1 + 1e-4)))
        assert not slipped.any(), (f"{bvh} BVH: {slipped.sum()} of {len(t)} rays aimed at a quad's diagonal "
                                   f"hit neither half, e.g. ray {np.flatnonzero(slipped)[:5]} (prim {prim[slipped][:5]})")
        assert on_pair.mean() > 0.8   # the test is not vacuous (the rest: the boxes, the overlapping bottom)
        assert np.allclose(t[on_pair], distance, rtol=1e-3)


def _fan(spokes=12, seed=5):
    """A flat fan of `spokes` triangles around a shared centre vertex, in a tilted plane, with
    irregular angles and radii: (vertices, triangles, normal)."""
    rng = np.random.default_rng(seed)
    center = np.array([0.0137, 0.2113, -0.1291])
    normal = _unit([0.31, 0.87, -0.38])
    u = _unit(np.cross(normal, [1.0, 0.0, 0.0]))
    w = np.cross(normal, u)
    angles = np.sort(rng.random(spokes)) * 2 * np.pi
    radii = 0.3 + 0.2 * rng.random(spokes)
    rim = center + radii[:, None] * (np.cos(angles)[:, None] * u + np.sin(angles)[:, None] * w)
    vertices = np.concatenate([[center], rim])
    triangles = np.array([[0, 1 + k, 1 + (k + 1) % spokes] for k in range(spokes)])
    return vertices, triangles, normal


def _fan_scene(cornell_box):
    """The fan alone with the Cornell box's light (a scene needs one), which hangs far above it."""
    vertices, triangles, normal = _fan()
    lights = cornell_box.light_triangles
    scene = replace(cornell_box, name="fan", vertices=np.concatenate([vertices, cornell_box.vertices]),
                    triangles=np.concatenate([triangles, cornell_box.triangles[lights] + len(vertices)]),
                    material_of=np.concatenate([np.zeros(len(triangles), cornell_box.material_of.dtype),
                                                cornell_box.material_of[lights]]),
                    emission_of=np.concatenate([np.zeros((len(triangles), 3)), cornell_box.emission_of[lights]]))
    return scene, vertices, triangles, normal


def test_no_ray_slips_through_a_shared_vertex_or_edge(queue, cornell_box):
    """Rays at the fan's centre vertex and at points on its spokes hit one of its triangles."""
    scene, vertices, triangles, normal = _fan_scene(cornell_box)
    center = DeviceScene(queue, scene, bvh="binary").center
    rng = np.random.default_rng(6)
    # The shared vertex exactly (its float32 device position), and points along every spoke.
    hub = vertices[0] - center
    hub = hub.astype(np.float32).astype(np.float64)
    s = np.array([1e-4, 0.01, 0.25, 0.5, 0.75])
    spokes = (vertices[0] + s[None, :, None] * (vertices[1:, None] - vertices[0])).reshape(-1, 3) - center
    targets = np.concatenate([np.repeat(hub[None], 8, axis=0), spokes])
    distance = 0.3
    origins, dirs = _rays(targets, normal, distance, rng)
    for bvh, (t, prim, _, _) in _cast(queue, scene, origins, dirs).items():
        slipped = (prim < 0) | (prim >= len(triangles))
        assert not slipped.any(), (f"{bvh} BVH: {slipped.sum()} of {len(t)} rays aimed at a shared vertex or edge "
                                   f"of the fan slipped through, e.g. ray {np.flatnonzero(slipped)[:5]}")
        assert np.allclose(t, distance, rtol=1e-4)


@pytest.mark.parametrize("bvh", BVHS)
def test_the_fan_catches_a_ray_that_passes_beside_it_only_there(queue, cornell_box, bvh):
    """The check can fail: a ray aimed just outside the fan's rim hits nothing."""
    scene, vertices, triangles, normal = _fan_scene(cornell_box)
    ds = DeviceScene(queue, scene, bvh=bvh)
    outside = vertices[0] + 1.5 * (vertices[1] - vertices[0]) - ds.center
    o, d = _rays(outside[None], normal, 0.3, np.random.default_rng(7))
    _, prim = DeviceRaycaster(queue, ds).closest(o, d)[:2]
    assert not np.isin(prim, np.arange(len(triangles))).any()
