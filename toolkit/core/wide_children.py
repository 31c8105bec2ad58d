"""The wide BVH's choice of children (toolkit/core/bvh.py, _wide_children), compiled by numba
for big scenes: the same breadth-first walk as the Python one, which a million-triangle scene's
200,000 wide nodes kept busy for seconds. tests/test_bvh_build.py holds both to the same
children, indices, depths and stack sizes.
"""
import numpy as np
from numba import njit


@njit(cache=True)
def wide_children(right, is_leaf, area, width):
    """(kids (wide nodes, width) binary nodes, -1 in empty lanes; binary node -> its wide node or
    -1; depth per wide node; stack entries a ray may hold on reaching it). `right`: each inner
    binary node's right child (the left one follows it). A wide node starts from the binary
    node's two children and opens its inner child of largest surface area (the first such, in
    lane order) until it has `width`; its inner children are queued, breadth first."""
    n = len(right)
    kids = np.full((max(n, 1), width), -1, np.int64)
    index_of = np.full(n, -1, np.int64)
    room = max(n, 1)                   # wide nodes: at most one per binary node
    depth_of, stack_of = np.zeros(room, np.int64), np.zeros(room, np.int64)
    # The breadth-first queue, (binary node, depth, stack entries below it) per wide node to make.
    queue, queue_depth, queue_stacked = np.empty(room, np.int64), np.empty(room, np.int64), np.empty(room, np.int64)
    queue[0], queue_depth[0], queue_stacked[0] = 0, 1, 0
    index_of[0] = 0
    head, tail = 0, 1                  # the queue is wide node order: queue[w] becomes wide node w
    while head < tail:
        w, b = head, queue[head]
        head += 1
        row = kids[w]
        if is_leaf[b]:
            row[0], count = b, 1
        else:
            row[0], row[1], count = b + 1, right[b], 2
        while count < width:
            pick = -1
            for lane in range(count):
                k = row[lane]
                if not is_leaf[k] and (pick < 0 or area[k] > area[row[pick]]):
                    pick = lane
            if pick < 0:
                break
            k = row[pick]
            for lane in range(count, pick + 1, -1):    # make room after `pick`
                row[lane] = row[lane - 1]
            row[pick], row[pick + 1] = k + 1, right[k]
            count += 1
        depth_of[w] = queue_depth[w]
        stack_of[w] = queue_stacked[w] + count     # all children pushed, before the nearest is popped
        for lane in range(count):
            k = row[lane]
            if not is_leaf[k]:
                index_of[k] = tail
                queue[tail], queue_depth[tail] = k, queue_depth[w] + 1
                queue_stacked[tail] = queue_stacked[w] + count - 1
                tail += 1
    return kids[:tail], index_of, depth_of[:tail], stack_of[:tail]
