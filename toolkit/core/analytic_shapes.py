"""Mitsuba's analytic shapes as triangles, in their canonical frames (before `to_world`):

- rectangle: the square [-1, 1]^2 at z = 0, normal +z (2 triangles, exact);
- cube: [-1, 1]^3, normals outward (12 triangles, exact);
- disk: radius 1 at z = 0, normal +z: a fan of DISK_SEGMENTS triangles;
- sphere: radius 1 about the origin, normals outward: SPHERE_RINGS x 2 SPHERE_RINGS quads of
  latitude and longitude, each split in two.

The curved ones are tessellated with their vertices on the true surface. The chords cut inside
it: no point of a disk's edge is farther than DISK_ERROR (0.12%) of the radius from the circle,
and no point of a sphere's triangles farther than SPHERE_ERROR (0.24%) of the radius from the
sphere (tests/test_mitsuba_xml.py measures both). Their area, and so an emitter's power, is
smaller by about as much.
"""
import math

import numpy as np

DISK_SEGMENTS = 64
SPHERE_RINGS = 32
DISK_ERROR = 1 - math.cos(math.pi / DISK_SEGMENTS)
# A quad's centre is the point farthest from the sphere: half its diagonal's angle.
SPHERE_ERROR = 1 - math.cos(math.pi / SPHERE_RINGS / 2) * math.cos(math.pi / SPHERE_RINGS / 2)


def rectangle():
    vertices = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
    return vertices, np.array([[0, 1, 2], [0, 2, 3]])


def cube():
    """Each face's square, wound counter-clockwise seen from outside."""
    vertices, triangles = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            u, v = (axis + 1) % 3, (axis + 2) % 3       # (u, v, axis) is right-handed
            corners = np.zeros((4, 3))
            corners[:, axis] = sign
            corners[:, u] = [-1, 1, 1, -1]
            corners[:, v] = [-1, -1, 1, 1]
            base = len(vertices) * 4
            vertices.append(corners)
            quad = [[0, 1, 2], [0, 2, 3]] if sign > 0 else [[0, 2, 1], [0, 3, 2]]
            triangles.extend([[base + i for i in t] for t in quad])
    return np.concatenate(vertices), np.array(triangles)


def disk():
    angles = np.arange(DISK_SEGMENTS) * (2 * math.pi / DISK_SEGMENTS)
    rim = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], 1)
    vertices = np.concatenate([[[0.0, 0.0, 0.0]], rim])
    k = np.arange(DISK_SEGMENTS)
    return vertices, np.stack([np.zeros_like(k), 1 + k, 1 + (k + 1) % DISK_SEGMENTS], 1)


def sphere():
    """Latitude rings from the south pole (z = -1) to the north; the poles' quads are triangles."""
    n_lon = 2 * SPHERE_RINGS
    theta = np.arange(1, SPHERE_RINGS) * (math.pi / SPHERE_RINGS)          # from the north pole
    phi = np.arange(n_lon) * (2 * math.pi / n_lon)
    ring = np.stack([np.outer(np.sin(theta), np.cos(phi)), np.outer(np.sin(theta), np.sin(phi)),
                     np.repeat(np.cos(theta)[:, None], n_lon, 1)], -1).reshape(-1, 3)
    north, south = len(ring), len(ring) + 1
    vertices = np.concatenate([ring, [[0, 0, 1.0], [0, 0, -1.0]]])
    j = np.arange(n_lon)
    nxt = (j + 1) % n_lon
    triangles = [np.stack([np.full(n_lon, north), j, nxt], 1)]
    for r in range(SPHERE_RINGS - 2):
        a, b = r * n_lon + j, (r + 1) * n_lon + j
        c, d = r * n_lon + nxt, (r + 1) * n_lon + nxt
        triangles += [np.stack([a, b, d], 1), np.stack([a, d, c], 1)]
    last = (SPHERE_RINGS - 2) * n_lon
    triangles.append(np.stack([last + j, np.full(n_lon, south), last + nxt], 1))
    return vertices, np.concatenate(triangles)


SHAPES = {"rectangle": rectangle, "cube": cube, "disk": disk, "sphere": sphere}
