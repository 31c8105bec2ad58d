"""A binned SAH bounding-volume hierarchy built on the host, flattened for the device.

Two builders make the same tree, bit for bit: `_build_numpy`, one node at a time in numpy (the
one to read), and toolkit/core/sah_build.py, the same loops compiled by numba, for scenes of
COMPILED_FROM triangles or more (a million triangles: a minute in numpy, about a second
compiled), in a process of its own from SEPARATE_FROM triangles (build_process.py: numba's
memory leaves with it). tests/test_bvh_build.py holds them to the same nodes.

Nodes are stored depth-first: an inner node's left child follows it, `first` holds the right
child. Leaves hold at most `leaf_size` triangles, reordered so each leaf's are contiguous.

`collapse_wide` turns the binary BVH into a wide one of 4 or 8 children per node (WIDE_NODES): each
wide node takes the binary node's two children and keeps opening its largest inner child (by
surface area, the SAH's measure of how often a ray visits it) until it has that many. Every
binary leaf (at most four triangles, BVH_WIDTH) becomes one TriGroup, so both BVHs keep the
same triangle order and leaves.
"""
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from toolkit.core.layout import BVH_NODE, BVH_WIDTH, TRI_GROUP, WIDE_NODES, WideChild

# Builds of this many triangles or more are compiled (toolkit/core/sah_build.py; the wide BVH's
# choice of children too, from as many binary nodes): below, numpy's build (about 15,000
# triangles/s) takes no longer than numba's start (half a second to a second) and spares its 150 MB.
COMPILED_FROM = 15_000
# Builds of this many triangles or more run in a process of their own (build_process.py), which
# takes numba's 120 MB with it when it ends; the wide BVH's children of every width come from it
# too. Starting it costs about 0.2 s; a scene this big needs the memory.
SEPARATE_FROM = 250_000
# Builds of this many triangles or more show a progress bar, updated every PROGRESS_STEP triangles.
PROGRESS_FROM = 1_000_000
PROGRESS_STEP = 250_000


@dataclass
class Bvh:
    nodes: np.ndarray        # BVH_NODE.dtype
    order: np.ndarray        # triangle order: leaf slot -> scene triangle index
    build_seconds: float
    inner_nodes: int
    leaf_nodes: int
    max_depth: int
    # Width -> _wide_children's arrays for that width, where the build's process made them
    # (SEPARATE_FROM): this process then never starts numba. Empty otherwise (made when asked).
    children: dict = field(default_factory=dict)

    @property
    def node_count(self):
        return len(self.nodes)


def _area(lo, hi):
    d = np.maximum(hi - lo, 0.0)
    return 2.0 * (d[..., 0] * d[..., 1] + d[..., 1] * d[..., 2] + d[..., 2] * d[..., 0])


def build_bvh(vertices, triangles, leaf_size=4, bins=16):
    """Build over triangles (M, 3) of vertex indices into `vertices`, (V, 3) float64 positions.
    From COMPILED_FROM triangles on, the compiled build does it (toolkit/core/sah_build.py, the
    same tree bit for bit); a scene of PROGRESS_FROM triangles or more shows its progress."""
    start = time.perf_counter()
    if len(triangles) >= SEPARATE_FROM:
        return _build_separately(vertices, triangles, leaf_size, bins, start)
    if len(triangles) >= COMPILED_FROM:
        lo, hi, first, count, axis, order, depth = _build_compiled(vertices, triangles, leaf_size, bins)
    else:
        lo, hi, first, count, axis, order, depth = _build_numpy(vertices[triangles], leaf_size, bins)
    flat = _flat_nodes(lo, hi, first, count, axis)
    leaves = int((flat["count"] > 0).sum())
    return Bvh(flat, order, time.perf_counter() - start, len(flat) - leaves, leaves, depth)


NODE_ARRAYS = ("lo", "hi", "first", "count", "axis")     # the build's arrays, as BVH_NODE's fields


def _flat_nodes(lo, hi, first, count, axis):
    """The device's BVH_NODE records of the build's arrays."""
    flat = aligned_zeros(len(first) * BVH_NODE.dtype.itemsize).view(BVH_NODE.dtype)    # see aligned_zeros
    for name, array in zip(NODE_ARRAYS, (lo, hi, first, count, axis)):
        _set_nodes(flat, name, array)
    return flat


def _set_nodes(flat, name, array):
    """One of the build's arrays into the records' field of that name."""
    if name in ("lo", "hi"):
        # Round outwards so float32 boxes still contain the float32 triangles.
        flat[name][:, :3] = np.nextafter(array.astype(np.float32), np.float32(-np.inf if name == "lo" else np.inf))
    else:
        flat[name] = array


def _build_compiled(vertices, triangles, leaf_size, bins):
    """The compiled build in this process (sah_build.build: the subtrees below its top nodes in two threads)."""
    # Imported here: numba's start costs about half a second and 120 MB, which small scenes need not pay.
    from toolkit.core import sah_build
    return sah_build.build(vertices, triangles, leaf_size, bins, PROGRESS_STEP, len(triangles) >= PROGRESS_FROM)


def _build_separately(vertices, triangles, leaf_size, bins, start):
    """The compiled build and the wide BVH's children of each width, made by a process of its own
    (build_process.py); the same arrays as _build_compiled and _wide_children make here."""
    from toolkit.core.build_process import BuildProcess
    with BuildProcess() as child:
        child.send(np.ascontiguousarray(vertices, np.float64), np.ascontiguousarray(triangles, np.int64),
                   np.array([leaf_size, bins, PROGRESS_STEP, len(triangles) >= PROGRESS_FROM], np.int64))
        flat = None
        for name in NODE_ARRAYS:        # one at a time into the records: all five are 43 MB for a million triangles
            array, = child.receive(1)
            if flat is None:
                flat = aligned_zeros(len(array) * BVH_NODE.dtype.itemsize).view(BVH_NODE.dtype)
            _set_nodes(flat, name, array)
        order, depth = child.receive(2)
        child.send(_node_areas(flat), np.array(list(WIDE_NODES), np.int64))
        children = {width: tuple(child.receive(4)) for width in WIDE_NODES}
    leaves = int((flat["count"] > 0).sum())
    return Bvh(flat, order, time.perf_counter() - start, len(flat) - leaves, leaves, int(depth), children)


def _best_split(lo, hi, centroid, bins):
    """(cost, axis, mask_left) of the cheapest binned SAH split, or None if none exists."""
    cmin, cmax = centroid.min(0), centroid.max(0)
    best = None
    for axis in range(3):
        extent = cmax[axis] - cmin[axis]
        if extent <= 0:
            continue
        b = np.minimum(((centroid[:, axis] - cmin[axis]) / extent * bins).astype(np.int64), bins - 1)
        order = np.argsort(b, kind="stable")
        sb = b[order]
        starts = np.searchsorted(sb, np.arange(bins))
        counts = np.bincount(b, minlength=bins)
        nonempty = counts > 0
        blo = np.full((bins, 3), np.inf)
        bhi = np.full((bins, 3), -np.inf)
        blo[nonempty] = np.minimum.reduceat(lo[order], starts[nonempty])
        bhi[nonempty] = np.maximum.reduceat(hi[order], starts[nonempty])
        # Sweeps: bounds and counts of bins [0, i] from the left and [i+1, bins) from the right.
        llo, lhi = np.minimum.accumulate(blo), np.maximum.accumulate(bhi)
        rlo = np.minimum.accumulate(blo[::-1])[::-1]
        rhi = np.maximum.accumulate(bhi[::-1])[::-1]
        lcount = np.cumsum(counts)
        cost = (lcount[:-1] * _area(llo[:-1], lhi[:-1])
                + (len(b) - lcount[:-1]) * _area(rlo[1:], rhi[1:]))
        cost[(lcount[:-1] == 0) | (lcount[:-1] == len(b))] = np.inf
        i = int(np.argmin(cost))
        if np.isfinite(cost[i]) and (best is None or cost[i] < best[0]):
            best = (float(cost[i]), axis, b <= i)
    return best


def _build_numpy(tri_vertices, leaf_size, bins):
    """The build in numpy, one node at a time, over (M, 3, 3) float64 triangle vertices: what
    sah_build.py compiles, as it reads best."""
    lo_all, hi_all = tri_vertices.min(1), tri_vertices.max(1)
    centroid_all = 0.5 * (lo_all + hi_all)
    nodes = []            # [lo, hi, first, count, axis]
    order = []
    depth_max = 0
    stack = [(np.arange(len(tri_vertices)), None, 0)]  # (triangles, parent to patch, depth)
    while stack:
        ids, parent, depth = stack.pop()
        depth_max = max(depth_max, depth)
        me = len(nodes)
        if parent is not None:
            nodes[parent][2] = me  # this is the right child of `parent`
        lo, hi = lo_all[ids].min(0), hi_all[ids].max(0)
        split = None
        if len(ids) > leaf_size:
            split = _best_split(lo_all[ids], hi_all[ids], centroid_all[ids], bins)
            if split is None:  # all centroids coincide: split the list in half
                half = np.zeros(len(ids), bool)
                half[: len(ids) // 2] = True
                split = (0.0, 0, half)
        if split is None:
            nodes.append([lo, hi, len(order), len(ids), 0])
            order.extend(ids.tolist())
            continue
        _, axis, left = split
        nodes.append([lo, hi, -1, 0, axis])
        # Right pushed first so the left child is built next and lands at me + 1.
        stack.append((ids[~left], me, depth + 1))
        stack.append((ids[left], None, depth + 1))
    return (np.array([n[0] for n in nodes]).reshape(-1, 3), np.array([n[1] for n in nodes]).reshape(-1, 3),
            [n[2] for n in nodes], [n[3] for n in nodes], [n[4] for n in nodes], np.asarray(order, np.int64),
            depth_max)


@dataclass
class WideBvh:
    """The wide BVH as one buffer of 16-byte words: WideNode records (the root first), then
    TriGroup records. A child reference is a record's position in words, ~position for a leaf."""
    words: np.ndarray        # (n, 4) float32: the buffer the kernels get as `nodes`
    node_width: int          # children per node: 4 or 8 (WIDE_NODES)
    inner_nodes: int
    leaf_groups: int
    max_depth: int           # wide nodes on the longest root-to-leaf path
    stack_needed: int        # most traversal-stack entries a ray can need (cl/bvh.h)

    @property
    def node_words(self):
        return node_words(self.node_width)


def node_words(node_width):
    """16-byte words of one node of that width."""
    return WIDE_NODES[node_width].dtype.itemsize // 16


GROUP_WORDS = TRI_GROUP.dtype.itemsize // 16
# The kernels load an 8-wide node's float8 fields with aligned loads: in that BVH every record must
# start on 32 bytes, so both sizes are an even number of words (the buffer is allocated aligned).
assert GROUP_WORDS % 2 == 0 and node_words(8) % 2 == 0, "8-wide BVH records must be multiples of 32 bytes"


def collapse_wide(bvh, leaf_vertices, node_width, width=BVH_WIDTH):
    """The wide BVH of `bvh`: nodes of up to `node_width` children (4 or 8), leaves of up to
    `width` triangles. `leaf_vertices`: (M, 3, 3) float32 triangle vertices in leaf order (the
    device's triangles), or their three corners as three (M, 3 or more) arrays (the device's
    Triangle records' v0, v1, v2: no copy); copied into the TriGroups bit for bit."""
    corners = [leaf_vertices[:, v] for v in range(3)] if isinstance(leaf_vertices, np.ndarray) else leaf_vertices
    nodes = bvh.nodes
    is_leaf = nodes["count"] > 0
    if is_leaf.any() and nodes["count"].max() > width:
        raise ValueError(f"a TriGroup holds {width} triangles; the BVH has leaves of {nodes['count'].max()}")
    kids, index_of, depth_of, stack_of = bvh.children.get(node_width) or _wide_children(nodes, is_leaf, node_width)
    leaves = int(is_leaf.sum())
    # One buffer of words, zeroed, and the records written into it where they lie (no copy).
    split = len(kids) * WIDE_NODES[node_width].dtype.itemsize
    records = aligned_zeros(split + leaves * TRI_GROUP.dtype.itemsize)
    wide = records[:split].view(WIDE_NODES[node_width].dtype)
    groups = records[split:].view(TRI_GROUP.dtype)
    group_of = _tri_groups(nodes, is_leaf, corners, width, groups)
    used = kids >= 0
    k = kids[used]
    for axis, name in enumerate("xyz"):
        wide[f"lo_{name}"][used] = nodes["lo"][k, axis]
        wide[f"hi_{name}"][used] = nodes["hi"][k, axis]
    group_base = len(kids) * node_words(node_width)
    wide["child"] = int(WideChild.EMPTY)
    wide["child"][used] = np.where(is_leaf[k], ~(group_base + group_of[k] * GROUP_WORDS),
                                   index_of[k] * node_words(node_width))
    return WideBvh(records.view(np.float32).reshape(-1, 4), node_width, len(kids), len(groups), int(depth_of.max()),
                   int(stack_of.max()))


def aligned_zeros(nbytes, alignment=4096):
    """`nbytes` zero bytes (uint8) that start on a multiple of `alignment` (a page): a CPU device
    can use them as a buffer in place (device_scene.py, USE_HOST_PTR), and the 8-wide BVH's
    aligned loads find their records on 32 bytes there too."""
    raw = np.zeros(nbytes + alignment, np.uint8)
    start = -raw.ctypes.data % alignment
    return raw[start:start + nbytes]


def wide_stack_needed(bvh, node_width):
    """The traversal-stack entries collapse_wide(bvh, ..., node_width) will need (WideBvh.stack_needed),
    without making its records."""
    nodes = bvh.nodes
    return int((bvh.children.get(node_width) or _wide_children(nodes, nodes["count"] > 0, node_width))[3].max())


def _tri_groups(nodes, is_leaf, corners, width, groups):
    """One TriGroup per binary leaf, in node order, written into `groups` (zeroed records, one per
    leaf); returns binary node -> its group or -1."""
    leaves = np.flatnonzero(is_leaf)
    group_of = np.full(len(nodes), -1)
    group_of[leaves] = np.arange(len(leaves))
    groups["tri"] = -1
    first, count = nodes["first"][leaves], nodes["count"][leaves]
    for lane in range(width):
        has = lane < count
        slot = first[has] + lane
        groups["tri"][has, lane] = slot
        for v in range(3):
            for k, name in enumerate("xyz"):
                # Empty lanes keep v0 = v1 = v2 = 0: a degenerate triangle the test rejects (det = 0).
                groups[f"v{v}{name}"][has, lane] = corners[v][slot, k]
    return group_of


def _node_areas(nodes):
    """Each node's surface area, of its float32 box (the one the device tests), in float64."""
    return _area(nodes["lo"][:, :3].astype(np.float64), nodes["hi"][:, :3].astype(np.float64))


def _wide_children(nodes, is_leaf, width):
    """The wide nodes' children, chosen top-down (the inner child of largest surface area opens
    first): (binary children per wide node (wide nodes, width), -1 in empty lanes; binary node ->
    wide node index for inner children, else -1; depth per wide node; stack entries a ray may
    hold on reaching it). Big trees take the compiled walk (toolkit/core/wide_children.py)."""
    area = _node_areas(nodes)
    if len(nodes) >= COMPILED_FROM:
        from toolkit.core.wide_children import wide_children      # numba: see build_bvh
        return wide_children(nodes["first"].astype(np.int64), is_leaf, area, width)

    def children(b):
        return [b + 1, int(nodes["first"][b])]

    kids_of, depth_of, stack_of = [], [], []
    pending = deque([(0, 1, 0)])  # (binary node, depth, stack entries below it), breadth first
    index_of = np.full(len(nodes), -1)
    index_of[0] = 0
    while pending:
        b, depth, stacked = pending.popleft()
        kids = [b] if is_leaf[b] else children(b)
        while len(kids) < width:
            inner = [k for k in kids if not is_leaf[k]]
            if not inner:
                break
            k = max(inner, key=lambda k: area[k])
            i = kids.index(k)
            kids[i:i + 1] = children(k)
        kids_of.append(kids + [-1] * (width - len(kids)))
        depth_of.append(depth)
        stack_of.append(stacked + len(kids))    # all children pushed, before the nearest is popped
        for k in kids:
            if not is_leaf[k]:
                index_of[k] = len(kids_of) + len(pending)
                pending.append((k, depth + 1, stacked + len(kids) - 1))
    return np.array(kids_of, np.int64), index_of, np.array(depth_of), np.array(stack_of)
