/* BDPT, connect phase in parallel (the talk's "Parallel Bidirectional Connect"): one
 * work-item per connection, so every lane of a warp evaluates one connection.
 *   1. each pool slot writes its number of connections (0 unless its sample terminated);
 *   2. an exclusive scan of those counts gives each sample its first connection index
 *      (bdpt_list_offsets and bdpt_list_terminated, cl/bdpt_walk.h), and the total;
 *   3. work-item g finds its sample by binary search: the last slot whose first index
 *      is <= g; its local index g - first picks the strategy (s, t).
 * Worked example: counts [0, 3, 0, 2] scan to firsts [0, 0, 3, 3], total 5.
 *   g = 0, 1, 2: the last slot with first <= g is slot 1 (slot 0 has the same first but
 *   comes before); local indices 0, 1, 2.  g = 3, 4: slot 3, local 0, 1.
 *   With n_light = 1 (only y_0) and n_eye = 2 (z_0, z_1), slot 1's 3 strategies are
 *   local 0 -> (s, t) = (1, 1), local 1 -> (0, 2), local 2 -> (1, 2)   (k + 1 = (t - 1)(n_light + 1) + s).
 * Kernels this technique launches, in the order of one pass (toolkit/techniques/bdpt_evaluator.py):
 *   bdpt_regenerate              cl/bdpt_walk.h   start samples in free pool slots
 *   bdpt_extend                  cl/bdpt_walk.h   one random-walk step of the eye and the light stream
 *   bdpt_parallel_connect_count  here             step 1
 *   bdpt_mark_terminated         cl/bdpt_walk.h   if enough have terminated, mark their slots (SLOT_CONNECTING)
 *   bdpt_list_offsets            cl/bdpt_walk.h   } step 2 for the marked slots, and the list of them
 *   bdpt_list_terminated         cl/bdpt_walk.h   }   (which regeneration restarts)
 *   (more walk steps, while the host's read of the counts comes back)
 *   bdpt_parallel_connect        here             step 3 */
#include "bdpt_walk.h"

__kernel void bdpt_parallel_connect_count(const int pool, __global const BdptSlot* slots, __global int* counts)
{
    int gid = get_global_id(0);
    if (gid >= pool) return;
    BdptSlot sample = slots[gid];
    counts[gid] = sample.live == SLOT_TERMINATED ? connection_count(sample.light_vertices, sample.eye_vertices) : 0;
}

/* The last index i in [0, n) with firsts[i] <= g (firsts is non-decreasing, firsts[0] = 0). */
HELPER int find_sample(__global const int* firsts, int n, int g) {
    int lo = 0, hi = n;            /* invariant: firsts[lo] <= g, answer in [lo, hi) */
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (firsts[mid] <= g) lo = mid; else hi = mid;
    }
    return lo;
}

/* One connection per work-item; record g holds its value and target pixel (-1: none). */
__kernel void bdpt_parallel_connect(SCENE_PARAMS, const Camera cam, const int total, const int pool, CONNECT_PARAMS)
{
    int gid = get_global_id(0);
    if (gid >= total) return;
    SceneView scene = SCENE_INIT;
    int slot = find_sample(firsts, pool, gid);
    int local_index = gid - firsts[slot];
    BdptSlot sample = slots[slot];
    int s_len, t_len;
    connection_strategy(local_index, sample.light_vertices, &s_len, &t_len);
    int steps = 0;
    Connection c = connect_strategy(&scene, &cam, eye_vertices + vertex_index(slot, 0),
                                    light_vertices + vertex_index(slot, 0), s_len, t_len,
                                    sample.pixel, &steps);
    record_value[gid] = connection_record(&c);
    record_pixel[gid] = c.pixel;
#if COUNT_SIMD
    LaneCounts lane = {.work = 1, .shadow_rays = 0, .shadow_steps = steps};
    lane_counts[gid] = lane;
#endif
}
