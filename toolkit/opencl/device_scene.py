"""A scene uploaded for the kernels: BVH, triangles in leaf order, materials, lights, camera.

Precision: the host subtracts the scene's centre in float64 before converting to float32, so
a scene translated far from the origin keeps the precision of one at the origin
("camera-relative" / origin rebasing). Ray offsets scale with the scene's size (scene_epsilon).
"""
import hashlib

import numpy as np
import pyopencl as cl

from toolkit.core.bvh import SEPARATE_FROM, aligned_zeros, build_bvh, collapse_wide, wide_stack_needed
from toolkit.core.record import frozen
from toolkit.core.layout import BVH_KINDS, BVH_STACK_SIZE, CAMERA, LIGHT, LUMINANCE_WEIGHTS, MATERIAL, MATERIAL_TYPES, SCENE_ARGS, TRIANGLE, WIDE_NODES
from toolkit.opencl import lanes
from toolkit.opencl.session import session


def _rebased(scene):
    """The scene's vertices less the centre of their box (float64 rebasing), and that centre."""
    lo, hi = scene.vertices.min(0), scene.vertices.max(0)
    center = 0.5 * (lo + hi)
    return scene.vertices - center, center


def _key(scene, local):
    # Vertices and indices hashed where they lie, not every triangle's vertices (72 MB for a million).
    digest = hashlib.blake2b(digest_size=16)
    for array in (local, scene.triangles):
        array = np.ascontiguousarray(array)
        digest.update(str((array.dtype.str, array.shape)).encode())
        digest.update(array.data)
    return scene.name, digest.digest()


def build_ahead(scene):
    """Build a big scene's host BVH now, before the OpenCL context is made (toolkit.render): the
    build's own process (from SEPARATE_FROM triangles, about 330 MB for a million) then ends before
    the runtime's context (about 140 MB) exists, and the two never take memory at the same time.
    The next DeviceScene of this geometry takes it. A smaller scene's is built where it is needed."""
    if len(scene.triangles) < SEPARATE_FROM:
        return
    local, _ = _rebased(scene)
    key = _key(scene, local)
    kept = session()
    if key not in kept.built_ahead and key not in kept.held_bvhs:
        kept.built_ahead[key] = build_bvh(local, scene.triangles)


def _bvh_for(queue, scene, local):
    """The host BVH of this geometry (`local`: the rebased vertices), built once per context (its
    Builds keeps it: builds.py), or taken from build_ahead or another context."""
    bvhs = queue.builds.bvhs
    key = _key(scene, local)
    if key not in bvhs:
        kept = session()
        bvhs[key] = kept.built_ahead.pop(key, None) or kept.held_bvhs.get(key) or build_bvh(local, scene.triangles)
        kept.held_bvhs[key] = bvhs[key]
    return bvhs[key]


def node_width(queue):
    """Children per wide-BVH node for kernels built with `queue`: 8 where each work-item is a
    thread of its own, 4 where work-items run as SIMD lanes (a GPU, Intel's runtime with lanes on).
    A thread tests a node's boxes with vector operations, and eight float32s fill one AVX
    register, so an 8-wide node costs about what a 4-wide one does and the tree is shallower
    (surface rays on cornell_spheres: 9.5 inner nodes per ray instead of 14.3, 0.85x Embree's
    rays/s to 1.0x). Where work-items are lanes, each float8 operation is eight operations
    across the lanes: there 8 children made pt_naive a quarter slower (cornell_spheres 64x64)."""
    return 4 if queue.builds.lanes in ("on", lanes.HARDWARE) else 8


def _host_memory_flag(device):
    """How the scene's arrays become buffers. A CPU device's memory is the host's: there the
    buffers are the arrays themselves (USE_HOST_PTR; a million triangles' nodes and triangles
    are 130 MB, which a copy would double). Other devices get a copy (COPY_HOST_PTR): a GPU
    must not traverse its BVH across the bus. The arrays are never written after this, and a
    buffer made with USE_HOST_PTR keeps its array alive (pyopencl holds it)."""
    return cl.mem_flags.USE_HOST_PTR if device.type & cl.device_type.CPU else cl.mem_flags.COPY_HOST_PTR


class DeviceScene:
    # Relative size of the ray offset: far above float32 rounding (~1e-7) of a hit point,
    # far below any gap between surfaces in the scenes (the Cornell light hangs 0.3% below the ceiling).
    EPSILON_RELATIVE = 1e-5

    def __init__(self, queue, scene, bvh="wide", wide_width=None):
        """`bvh`: "wide" (4 or 8 children per node, tested together with vector operations;
        `wide_width`, by default node_width(queue)) or "binary" (two per node); the
        kernels are built for it (features())."""
        if bvh not in BVH_KINDS:
            raise ValueError(f"bvh must be one of {', '.join(BVH_KINDS)}, got {bvh!r}")
        if wide_width not in (None, *WIDE_NODES):
            raise ValueError(f"wide_width must be one of {', '.join(map(str, WIDE_NODES))}, got {wide_width!r}")
        self.bvh_kind = bvh
        self.scene = scene
        self.queue = queue
        local, self.center = _rebased(scene)
        self.extent = float(np.linalg.norm(scene.vertices.max(0) - scene.vertices.min(0)))
        self.epsilon = np.float32(self.EPSILON_RELATIVE * self.extent)
        self.bvh = _bvh_for(queue, scene, local)
        if self.bvh.max_depth >= BVH_STACK_SIZE - 1:
            raise ValueError(f"{scene.name}: BVH depth {self.bvh.max_depth} exceeds the device stack ({BVH_STACK_SIZE})")
        order = self.bvh.order
        # Rounded to float32 vertex by vertex, then gathered corner by corner: the same numbers as
        # gathering in float64 and rounding, without a copy of every triangle's vertices (a
        # million triangles: 72 MB in float64, 36 in float32); the wide BVH reads them from here.
        local32 = local.astype(np.float32)
        self.triangles = aligned_zeros(len(order) * TRIANGLE.dtype.itemsize).view(TRIANGLE.dtype)
        corners = [self.triangles[f"v{v}"] for v in range(3)]
        for v in range(3):
            corners[v][:, :3] = local32[scene.triangles[order, v]]
        del local32
        self.triangles["material"] = scene.material_of[order]
        self.triangles["prim"] = order
        self.triangles["light"] = -1
        nodes = self.bvh.nodes
        self.wide = None
        if bvh == "wide":
            width = wide_width or node_width(queue)
            if wide_width is None and width == 8 and wide_stack_needed(self.bvh, 8) > BVH_STACK_SIZE:
                width = 4   # eight children a level fill the stack faster: a tree too deep for it gets four
            self.wide = collapse_wide(self.bvh, corners, width)
            if self.wide.stack_needed > BVH_STACK_SIZE:
                raise ValueError(f"{scene.name}: the wide BVH needs {self.wide.stack_needed} stack entries, "
                                 f"more than the device stack ({BVH_STACK_SIZE})")
            nodes = self.wide.words
        self._build_lights(local, order)
        self.materials = aligned_zeros(len(scene.materials) * MATERIAL.dtype.itemsize).view(MATERIAL.dtype)
        for i, m in enumerate(scene.materials):
            self.materials[i]["reflectance"][:3] = m["reflectance"]
            self.materials[i]["type"] = MATERIAL_TYPES[m["type"]]
            self.materials[i]["ior"] = m["ior"]
            self.materials[i]["alpha"] = m["alpha"]
        mf = cl.mem_flags.READ_ONLY | _host_memory_flag(queue.device)
        ctx = queue.context
        self.buffers = {name: cl.Buffer(ctx, mf, hostbuf=a) for name, a in
                        (("nodes", nodes), ("tris", self.triangles), ("materials", self.materials),
                         ("lights", self.lights))}

    def _build_lights(self, local, order):
        """Pick lights in proportion to power: area x luminance(emission). `local`: the rebased vertices."""
        scene = self.scene
        slot_of = np.empty(len(order), np.int64)
        slot_of[order] = np.arange(len(order))
        light_tris = scene.light_triangles
        v = local[scene.triangles[light_tris]]
        area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
        emission = scene.emission_of[light_tris]
        power = area * (emission @ np.array(LUMINANCE_WEIGHTS))
        power = np.where(power > 0, power, area * emission.max(1))
        prob = power / power.sum()
        self.lights = aligned_zeros(len(light_tris) * LIGHT.dtype.itemsize).view(LIGHT.dtype)
        self.lights["emission"][:, :3] = emission
        cdf = np.cumsum(prob)
        cdf[-1] = 1.0
        self.lights["cdf"] = cdf
        self.lights["triangle"] = slot_of[light_tris]
        self.triangles["light"][slot_of[light_tris]] = np.arange(len(light_tris))
        self.triangles["light_pdf"][slot_of[light_tris]] = prob / area

    def features(self, general=False):
        """The scene's compile-time defines (Scene.features; `general`: every code path) and the
        BVH traversal to build (the one this scene was uploaded for: a layout, not a feature)."""
        return dict(self.scene.features(general), BVH_WIDE=self.bvh_kind == "wide",
                    NODE_WIDTH=self.wide.node_width if self.wide is not None else None)

    def bvh_stats(self):
        """Sizes of the BVH the kernels traverse (for render stats and compare)."""
        stats = {"kind": self.bvh_kind, "binary_nodes": self.bvh.node_count, "leaves": self.bvh.leaf_nodes,
                 "binary_depth": self.bvh.max_depth, "build_seconds": self.bvh.build_seconds}
        if self.wide is not None:
            stats.update(wide_width=self.wide.node_width, wide_nodes=self.wide.inner_nodes, wide_depth=self.wide.max_depth,
                         wide_stack=self.wide.stack_needed)
        return stats

    def camera(self, width, height):
        """The Camera record for an image of width x height (same field of view as the scene's)."""
        cam = self.scene.camera
        forward, right, up = cam.basis(width, height)
        records = CAMERA.zeros(1)
        rec = records[0]
        rec["origin"][:3] = cam.origin - self.center
        rec["forward"][:3] = forward
        rec["right"][:3] = right
        rec["up"][:3] = up
        rec["width"], rec["height"] = width, height
        return frozen(records)    # the same object at every launch of the render (program.launch)

    def args(self):
        """The SCENE_PARAMS kernel arguments, in the order of layout.SCENE_ARGS."""
        values = dict(self.buffers, light_count=np.int32(len(self.lights)), epsilon=self.epsilon)
        return [values[name] for name, _ in SCENE_ARGS]
