/* Assignment 3: parallel connect indexing (van Antwerpen, HPG 2011, slide "Parallel
 * Bidirectional Connect"). Your file replaces the toolkit's cl/bdpt_parallel_connect.cl:
 *     python -m toolkit grade parallel_connect --kernel THIS_FILE
 * One work-item per connection, so every lane of a warp evaluates one connection:
 *   1. each pool slot writes its number of connections (0 unless its sample terminated);
 *   2. the host scans those counts (exclusive scan, toolkit/opencl/compaction.py): firsts[i] is the
 *      index of sample i's first connection, and the total is the number of work-items;
 *   3. work-item g finds its sample by binary search: the LAST slot whose first index is <= g
 *      (slots with no connections share their first index with the next slot); its local
 *      index g - firsts[slot] picks the strategy (s, t) with connection_strategy (cl/bdpt.h).
 * Worked example: counts [0, 3, 0, 2] scan to firsts [0, 0, 3, 3], total 5.
 *   g = 0, 1, 2 -> slot 1, local 0, 1, 2;   g = 3, 4 -> slot 3, local 0, 1.
 * Fill in the regions marked TODO; keep the names and arguments of the kernels and of find_sample. */
#include "bdpt_walk.h"

/* Step 1. A sample with n_light light and n_eye eye vertices has connection_count(n_light, n_eye)
 * strategies (cl/bdpt.h); a slot's sample is waiting for its connections when
 * live == SLOT_TERMINATED. */
__kernel void bdpt_parallel_connect_count(const int pool, __global const BdptSlot* slots, __global int* counts)
{
    int gid = get_global_id(0);
    if (gid >= pool) return;
    BdptSlot sample = slots[gid];
    /* TODO: counts[gid] = the number of connections of this slot */
    (void)sample;
    counts[gid] = 0;
}

/* Step 3. The last index i in [0, n) with firsts[i] <= g (firsts is non-decreasing, firsts[0] = 0).
 * O(log n) reads of firsts. */
static inline int find_sample(__global const int* firsts, int n, int g) {
    /* TODO: binary search */
    (void)firsts; (void)n; (void)g;
    return 0;
}

/* One connection per work-item; record g holds its value and target pixel (-1: none). */
__kernel void bdpt_parallel_connect(SCENE_PARAMS, const Camera cam, const int total, const int pool,
                                    __global const int* firsts, __global const BdptSlot* slots,
                                    __global const BdptVertex* eye_vertices, __global const BdptVertex* light_vertices,
                                    __global float4* record_value, __global int* record_pixel,
                                    __global LaneCounts* lane_counts)
{
    int gid = get_global_id(0);
    if (gid >= total) return;
    SceneView scene = SCENE_INIT;
    int slot = find_sample(firsts, pool, gid);
    /* TODO: this work-item's connection among its sample's connections (0, 1, ...) */
    int local_index = 0;
    BdptSlot sample = slots[slot];
    int s_len, t_len;
    connection_strategy(local_index, sample.light_vertices, &s_len, &t_len);
    int steps = 0;
    Connection c = connect_strategy(&scene, &cam, eye_vertices + vertex_index(slot, 0),
                                    light_vertices + vertex_index(slot, 0), s_len, t_len,
                                    sample_pixel(&cam, sample.sample_id), &steps);
    record_value[gid] = (float4)(c.value, c.weight);
    record_pixel[gid] = c.pixel;
#if COUNT_SIMD
    LaneCounts lane = {.work = 1, .shadow_rays = 0, .shadow_steps = steps};
    lane_counts[gid] = lane;
#else
    (void)lane_counts;
#endif
}
