"""The binned SAH build of toolkit/core/bvh.py, compiled to machine code by numba.

The algorithm is the one a textbook gives (Wald 2007, "On fast construction of SAH-based bounding
volume hierarchies"; pbrt-v4 section 7.3): split a node's triangles where the surface area
heuristic, cost = N_left * area_left + N_right * area_right, is least among the boundaries of
BINS equal bins of the centroids' extent on each axis. Written as plain loops over triangles,
it is what numpy cannot do fast: every node is a different small problem, and Python's loop over
a million triangles' nodes took a minute. numba compiles the loops once (and caches the machine
code on disk), and the build runs at about a million triangles per second on one core.

The tree is the same, bit for bit, as numpy's build of the same algorithm gave: every float64
operation is written in numpy's order (no fast-math, no fused multiply-add: numba leaves both
off unless asked), ties go to the lower bin and then the lower axis, as np.argmin and a strict
`<` did, and partitions keep the triangles' order. tests/test_bvh_build.py holds the two
builders to the same nodes on random and bundled scenes.

The build is resumable: `build_some` works until `budget` more triangles sit in leaves and
returns, so the caller can show progress between calls on a big scene. And a state builds one
range of triangles, apart from any other: `build` makes the top few nodes one at a time, builds
the subtrees below them at once, in two threads, and `join` makes one tree of them.

This file imports numpy and numba only, never the toolkit: build_process.py runs it in a
process of its own for big scenes.
"""
import sys

import numpy as np
from numba import njit

# Counters of a build in progress (BuildState.counters).
NODES, STACKED, PLACED, DEPTH = range(4)
# Room a state makes at first: nodes per triangle (a tree of leaves of up to four has about 0.6),
# and stack entries (one per level of the tree on the current path). A state that runs out of
# either doubles it and goes on.
NODE_ROOM, STACK_ROOM = 1.0, 64


class BuildState:
    """Everything a build of one range of triangles keeps between calls: each triangle's box and
    the triangles' order (`bounds` and `order`, shared by every state of one build), both
    partitioned in place (so each node's triangles are one range of them, read front to back,
    and at the end `order` is the leaves' order); the nodes made so far (depth-first: a left
    child follows its parent; numbered from 0 in each state); and the stack of ranges still to
    build, each with its boxes (a split measures its sides' boxes, so a child never measures its
    own). States of disjoint ranges can run at once, in threads of their own (numba's nogil)."""

    def __init__(self, bounds, order, start, end, depth, box):
        n = self.triangles = end - start
        self.bounds, self.order = bounds, order
        # The right side of a partition, before its copy back: a node's right side is at most n.
        self.scratch_bounds, self.scratch_order = np.empty((n, 6)), np.empty(n, np.int64)
        room = max(int(NODE_ROOM * n), 1)
        self.node_lo, self.node_hi = np.empty((room, 3)), np.empty((room, 3))
        self.node_first, self.node_count = np.empty(room, np.int64), np.empty(room, np.int64)
        self.node_axis = np.empty(room, np.int64)
        # A range waits on the stack: (start, end, parent to patch or -1, depth) and its boxes. The
        # right child of each node on the current path waits.
        self.stack, self.boxes = np.empty((STACK_ROOM, 4), np.int64), np.empty((STACK_ROOM, 12))
        self.stack[0], self.boxes[0] = (start, end, -1, depth), box
        self.counters = np.zeros(4, np.int64)
        self.counters[STACKED] = 1

    @classmethod
    def of_triangles(cls, vertices, triangles):
        """The state of a whole build: triangles (M, 3) indexing vertices (V, 3)."""
        bounds, box = np.empty((len(triangles), 6)), np.empty(12)
        # Per triangle: lo x, y, z, hi x, y, z. Its centroid is 0.5 * (lo + hi), computed when needed.
        _measure(np.ascontiguousarray(vertices, np.float64), np.ascontiguousarray(triangles, np.int64), bounds, box)
        return cls(bounds, np.arange(len(triangles), dtype=np.int64), 0, len(triangles), 0, box)

    def run(self, budget, leaf_size, bins, max_nodes=1 << 62):
        """Build until `budget` more triangles are in leaves (or all are), or `max_nodes` nodes
        are made; returns how many triangles are in leaves."""
        stop = self.counters[PLACED] + budget
        while True:
            placed = build_some(self.bounds, self.order, self.scratch_bounds, self.scratch_order, self.node_lo,
                                self.node_hi, self.node_first, self.node_count, self.node_axis, self.stack,
                                self.boxes, self.counters, stop - self.counters[PLACED], max_nodes, leaf_size, bins)
            if self.done or placed >= stop or self.nodes >= max_nodes:
                return placed
            self._make_room()        # it stopped for room: the nodes or the stack are full

    def _make_room(self):
        """Twice the room for nodes, or for waiting ranges, whichever is full."""
        def doubled(array):
            return np.concatenate([array, np.empty_like(array)])
        if self.nodes == len(self.node_first):
            self.node_lo, self.node_hi, self.node_first, self.node_count, self.node_axis = (
                doubled(a) for a in (self.node_lo, self.node_hi, self.node_first, self.node_count, self.node_axis))
        if self.counters[STACKED] == len(self.stack):
            self.stack, self.boxes = doubled(self.stack), doubled(self.boxes)

    @property
    def done(self):
        return self.counters[STACKED] == 0

    @property
    def nodes(self):
        return self.counters[NODES]

    def waiting(self):
        """A state for each range on the stack (the left child's first), the stack emptied. This
        state's scratch space goes first: the new states make their own."""
        self.scratch_bounds = self.scratch_order = None
        states = [BuildState(self.bounds, self.order, *self.stack[i, [0, 1, 3]], self.boxes[i])
                  for i in range(self.counters[STACKED] - 1, -1, -1)]
        self.counters[STACKED] = 0
        return states

    def release(self):
        """Let go of the triangles' boxes and the scratch space (a million triangles: up to 100 MB),
        once this state builds no more: the nodes and the order are what a build keeps."""
        self.bounds = self.scratch_bounds = self.scratch_order = None


def build(vertices, triangles, leaf_size, bins, step, progress, threads=2):
    """(lo, hi, first, count, axis, order, depth) of the tree over `triangles` (M, 3) indexing
    `vertices` (V, 3): the top nodes here, one at a time, until no range below them holds more
    than a (2 x threads)th of the triangles; then those ranges' subtrees at once, `threads` at a
    time, the biggest first, each resumed every `step` triangles; `progress`: show a progress bar.
    (Splitting at the root alone left one thread idle where one object is most of a scene: the
    million-triangle sphere beside its Cornell box made a root of 8 and of 998,028 triangles.)"""
    return build_from(BuildState.of_triangles(vertices, triangles), leaf_size, bins, step, progress, threads)


def build_from(root, leaf_size, bins, step, progress, threads=2):
    """build() from the state of the whole build (BuildState.of_triangles), which needs only the
    triangles' boxes: a caller can let go of the vertices and triangles first."""
    from concurrent.futures import ThreadPoolExecutor, wait
    from tqdm.auto import tqdm

    triangles = root.triangles
    subtrees = []
    top = _split_top(root, max(triangles // (2 * threads), 1), leaf_size, bins, subtrees)

    def build_subtree(state):
        while not state.done:
            state.run(step, leaf_size, bins)
        state.release()

    with tqdm(total=triangles, unit="tri", desc="BVH build", file=sys.stderr, leave=False,
              disable=not progress, mininterval=0.5) as bar, ThreadPoolExecutor(threads) as pool:
        running = [pool.submit(build_subtree, state) for state in sorted(subtrees, key=lambda s: -s.triangles)]
        while wait(running, timeout=0.5).not_done:
            bar.update(sum(state.counters[PLACED] for state in subtrees) - bar.n)
        for done in running:
            done.result()           # raises what the thread raised
    lo, hi, first, count, axis, depth = join(top)
    return lo, hi, first, count, axis, root.order, int(depth)


def _split_top(state, most, leaf_size, bins, subtrees):
    """The top of the tree as nested (state that made one node, left, right), down to the states
    of at most `most` triangles, which are appended to `subtrees` (built later, each whole)."""
    if state.triangles <= most:
        subtrees.append(state)
        return state
    state.run(state.triangles, leaf_size, bins, max_nodes=1)
    if state.done:                  # its one node is a leaf
        return state
    left, right = state.waiting()
    state.release()
    return state, _split_top(left, most, leaf_size, bins, subtrees), _split_top(right, most, leaf_size, bins, subtrees)


def join(top):
    """The arrays (lo, hi, first, count, axis, depth) of one depth-first tree from _split_top's
    nesting: a node made alone, then its left subtree's nodes, then its right one's. Each
    state's nodes move as a block, and each inner node's `first` (its right child) with them;
    leaves' `first` are positions in `order`, shared by all."""
    blocks, right_child = [], {}        # (where a state's nodes go, state, how many); split node -> its right child

    def place(part, at):
        if isinstance(part, BuildState):
            blocks.append((at, part, part.nodes))
            return at + part.nodes
        state, left, right = part
        blocks.append((at, state, 1))
        right_child[at] = place(left, at + 1)
        return place(right, right_child[at])

    total = place(top, 0)
    lo, hi = np.empty((total, 3)), np.empty((total, 3))
    first, count, axis = (np.empty(total, np.int64) for _ in range(3))
    for at, state, n in blocks:
        lo[at:at + n], hi[at:at + n] = state.node_lo[:n], state.node_hi[:n]
        count[at:at + n], axis[at:at + n] = state.node_count[:n], state.node_axis[:n]
        inner = state.node_count[:n] == 0
        first[at:at + n] = np.where(inner, state.node_first[:n] + at, state.node_first[:n])
        # Copied: the state's nodes go (a million triangles' are 43 MB, which the copy doubled).
        state.node_lo = state.node_hi = state.node_first = state.node_count = state.node_axis = None
    for at, right in right_child.items():
        first[at] = right
    depth = max(state.counters[DEPTH] for _, state, _ in blocks)
    return lo, hi, first, count, axis, depth


# A range's boxes, 12 numbers (BuildState.boxes): its triangles' box lo x, y, z, hi x, y, z, then
# their centroids' box the same way.

@njit(cache=True)
def _empty(box):
    """Boxes that hold nothing yet: lo and centroid lo +inf, hi and centroid hi -inf."""
    box[0:3], box[3:6], box[6:9], box[9:12] = np.inf, -np.inf, np.inf, -np.inf


@njit(cache=True)
def _grow(box, bounds, k):
    """Widen boxes by triangle k (a row of `bounds`)."""
    for j in range(3):
        c = 0.5 * (bounds[k, j] + bounds[k, 3 + j])
        box[j], box[3 + j] = min(box[j], bounds[k, j]), max(box[3 + j], bounds[k, 3 + j])
        box[6 + j], box[9 + j] = min(box[6 + j], c), max(box[9 + j], c)


@njit(cache=True)
def _measure(vertices, triangles, bounds, box):
    """Each triangle's box into `bounds`, and the boxes of all of them into `box`."""
    _empty(box)
    for k in range(len(triangles)):
        a, b, c = triangles[k, 0], triangles[k, 1], triangles[k, 2]
        for j in range(3):
            bounds[k, j] = min(vertices[a, j], vertices[b, j], vertices[c, j])
            bounds[k, 3 + j] = max(vertices[a, j], vertices[b, j], vertices[c, j])
        _grow(box, bounds, k)


@njit(cache=True)
def _area(dx, dy, dz):
    """Surface area of a box of these sides (negative sides count as 0), in numpy's order."""
    dx, dy, dz = max(dx, 0.0), max(dy, 0.0), max(dz, 0.0)
    return 2.0 * (dx * dy + dy * dz + dz * dx)


@njit(cache=True)
def _bin_of(c, cmin, extent, bins):
    """The bin of a centroid coordinate, as numpy computed it: ((c - cmin) / extent * bins) truncated."""
    b = np.int64((c - cmin) / extent * bins)
    return min(b, bins - 1)


@njit(cache=True)
def _add(blo, bhi, counts, axis, b, x0, y0, z0, x1, y1, z1):
    """A triangle of box (x0, y0, z0) .. (x1, y1, z1) into bin b of `axis`."""
    counts[axis, b] += 1
    blo[axis, b, 0], blo[axis, b, 1], blo[axis, b, 2] = min(blo[axis, b, 0], x0), min(blo[axis, b, 1], y0), \
        min(blo[axis, b, 2], z0)
    bhi[axis, b, 0], bhi[axis, b, 1], bhi[axis, b, 2] = max(bhi[axis, b, 0], x1), max(bhi[axis, b, 1], y1), \
        max(bhi[axis, b, 2], z1)


@njit(cache=True)
def _fill_bins(bounds, start, end, box, bins, blo, bhi, counts):
    """Counts and boxes of the triangles in each bin of each axis, one pass over bounds[start:end]
    for all three axes (an axis whose centroids do not spread is left empty). What the loop reads
    is copied into scalars first: the compiler cannot know that writing a bin leaves it alone,
    and would read it again (a third slower)."""
    blo[:], bhi[:], counts[:] = np.inf, -np.inf, 0
    cx, cy, cz = box[6], box[7], box[8]
    ex, ey, ez = box[9] - cx, box[10] - cy, box[11] - cz
    for k in range(start, end):
        x0, y0, z0, x1, y1, z1 = bounds[k, 0], bounds[k, 1], bounds[k, 2], bounds[k, 3], bounds[k, 4], bounds[k, 5]
        if ex > 0.0:
            _add(blo, bhi, counts, 0, _bin_of(0.5 * (x0 + x1), cx, ex, bins), x0, y0, z0, x1, y1, z1)
        if ey > 0.0:
            _add(blo, bhi, counts, 1, _bin_of(0.5 * (y0 + y1), cy, ey, bins), x0, y0, z0, x1, y1, z1)
        if ez > 0.0:
            _add(blo, bhi, counts, 2, _bin_of(0.5 * (z0 + z1), cz, ez, bins), x0, y0, z0, x1, y1, z1)


@njit(cache=True)
def _best_split(n, box, bins, blo, bhi, counts, rlo, rhi):
    """(axis, last bin of the left side) of the cheapest binned SAH split of filled bins, or
    (-1, -1) if none exists (all centroids coincide). rlo, rhi: room for the sweep from the right."""
    best_cost, best_axis, best_bin = np.inf, -1, -1
    llo, lhi = np.empty(3), np.empty(3)
    for axis in range(3):
        if box[9 + axis] - box[6 + axis] <= 0.0:
            continue
        # Bounds of bins [i, bins) from the right; the left side's grow in the loop below.
        rlo[bins - 1, :], rhi[bins - 1, :] = blo[axis, bins - 1, :], bhi[axis, bins - 1, :]
        for i in range(bins - 2, -1, -1):
            for j in range(3):
                rlo[i, j] = min(rlo[i + 1, j], blo[axis, i, j])
                rhi[i, j] = max(rhi[i + 1, j], bhi[axis, i, j])
        llo[:], lhi[:] = np.inf, -np.inf
        left = 0
        for i in range(bins - 1):        # the boundary after bin i
            for j in range(3):
                llo[j] = min(llo[j], blo[axis, i, j])
                lhi[j] = max(lhi[j], bhi[axis, i, j])
            left += counts[axis, i]
            if left == 0 or left == n:
                continue
            cost = (left * _area(lhi[0] - llo[0], lhi[1] - llo[1], lhi[2] - llo[2])
                    + (n - left) * _area(rhi[i + 1, 0] - rlo[i + 1, 0], rhi[i + 1, 1] - rlo[i + 1, 1],
                                         rhi[i + 1, 2] - rlo[i + 1, 2]))
            if cost < best_cost:         # strict: ties keep the lower bin, then the lower axis
                best_cost, best_axis, best_bin = cost, axis, i
    return best_axis, best_bin


@njit(cache=True)
def _push(stack, boxes, counters, start, end, parent, depth, box):
    top = counters[STACKED]
    stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = start, end, parent, depth
    boxes[top, :] = box
    counters[STACKED] += 1


@njit(cache=True, nogil=True)
def build_some(bounds, order, scratch_bounds, scratch_order, node_lo, node_hi, node_first, node_count, node_axis,
               stack, boxes, counters, budget, max_nodes, leaf_size, bins):
    """Pop node ranges and build them depth first (see BuildState) until `budget` more triangles
    sit in leaves, `max_nodes` nodes are made, the stack is empty, or there is no room for one
    more node or one more waiting range (BuildState.run makes room); returns the triangles in
    leaves. Holds no lock of Python's (nogil): two threads can build two subtrees at once."""
    stop = counters[PLACED] + budget
    blo, bhi, counts = np.empty((3, bins, 3)), np.empty((3, bins, 3)), np.empty((3, bins), np.int64)
    rlo, rhi = np.empty((bins, 3)), np.empty((bins, 3))
    box, left_box, right_box = np.empty(12), np.empty(12), np.empty(12)
    while (counters[STACKED] > 0 and counters[PLACED] < stop and counters[NODES] < max_nodes
           and counters[NODES] < len(node_first) and counters[STACKED] < len(stack)):
        counters[STACKED] -= 1
        top = counters[STACKED]
        start, end, parent, depth = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
        box[:] = boxes[top]
        counters[DEPTH] = max(counters[DEPTH], depth)
        me = counters[NODES]
        counters[NODES] += 1
        if parent >= 0:
            node_first[parent] = me          # this is the right child of `parent`
        node_lo[me, :], node_hi[me, :] = box[0:3], box[3:6]
        n = end - start
        if n <= leaf_size:
            node_first[me], node_count[me], node_axis[me] = start, n, 0
            counters[PLACED] += n            # depth first, left first: ranges become leaves in order
            continue
        _fill_bins(bounds, start, end, box, bins, blo, bhi, counts)
        axis, last_left_bin = _best_split(n, box, bins, blo, bhi, counts, rlo, rhi)
        # Stable partition: the left side's triangles first, each side in its old order; the
        # sides' boxes are measured on the way (min and max are exact: the same as measured later).
        _empty(left_box)
        _empty(right_box)
        if axis < 0:                         # all centroids coincide: split the list in half
            axis, middle = 0, start + n // 2
            for k in range(start, end):
                _grow(left_box if k < middle else right_box, bounds, k)
        else:
            cmin, extent = box[6 + axis], box[9 + axis] - box[6 + axis]
            middle, right = start, 0
            for k in range(start, end):
                if _bin_of(0.5 * (bounds[k, axis] + bounds[k, 3 + axis]), cmin, extent, bins) <= last_left_bin:
                    _grow(left_box, bounds, k)
                    order[middle], bounds[middle, :] = order[k], bounds[k, :]     # middle <= k
                    middle += 1
                else:
                    _grow(right_box, bounds, k)
                    scratch_order[right], scratch_bounds[right, :] = order[k], bounds[k, :]
                    right += 1
            order[middle:end], bounds[middle:end, :] = scratch_order[:right], scratch_bounds[:right, :]
        node_first[me], node_count[me], node_axis[me] = -1, 0, axis
        # Right pushed first so the left child is built next and lands at me + 1.
        _push(stack, boxes, counters, middle, end, me, depth + 1, right_box)
        _push(stack, boxes, counters, start, middle, -1, depth + 1, left_box)
    return counters[PLACED]
