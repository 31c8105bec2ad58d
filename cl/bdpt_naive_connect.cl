/* BDPT, connect phase the plain way: the work-item of each sample slot loops over all the
 * (s, t) strategies of its sample if it has terminated, and idles otherwise. The number of
 * strategies grows with the product of the two subpath lengths, so the lanes of a warp wait
 * for the sample with the longest paths, and lanes whose sample is still walking wait too
 * (the talk: ~17% active threads). The random walk is shared with bdpt_parallel_connect
 * (bdpt_walk.h).
 * Kernels this technique launches, in the order of one pass (toolkit/techniques/bdpt_evaluator.py):
 *   bdpt_regenerate        cl/bdpt_walk.h   start samples in free pool slots
 *   bdpt_extend            cl/bdpt_walk.h   one random-walk step of the eye and the light stream
 *   bdpt_naive_connect_splats  here         how many light-tracing (t = 1) records each terminated slot writes
 *   bdpt_mark_terminated   cl/bdpt_walk.h   if enough have terminated, mark their slots (SLOT_CONNECTING)
 *   bdpt_list_offsets      cl/bdpt_walk.h   } the scan of the listed slots' records (where each slot's
 *   bdpt_list_terminated   cl/bdpt_walk.h   } records start) and the list of the listed slots
 *   (more walk steps, while the host's read of the counts comes back)
 *   bdpt_naive_connect     here             every (s, t) strategy of a listed sample, in its slot's work-item
 * The scan only packs the records, so that the film adds the records written and not
 * MAX_VERTICES places per slot; the connections themselves are evaluated the plain way. */
#include "bdpt_walk.h"

/* Light-tracing records of each slot: one per s = 1 .. n_light (t = 1) if its sample terminated
 * (counted before bdpt_mark_terminated makes the listed ones SLOT_CONNECTING). */
__kernel void bdpt_naive_connect_splats(const int pool, __global const BdptSlot* slots, __global int* counts)
{
    int gid = get_global_id(0);
    if (gid >= pool) return;
    BdptSlot sample = slots[gid];
    counts[gid] = sample.live == SLOT_TERMINATED ? sample.light_vertices : 0;
}

/* Records (toolkit/core/bdpt_indices.py, shared with the host): slot k's t = 1 splats at
 * naive_splat_record(firsts[k], s) (firsts: the scan of the splat counts, `splats` records in
 * all), then the sum of its eye-path strategies at naive_sum_record(splats, k) (pixel -1:
 * nothing: every record's pixel is written, so the host clears nothing). Built for per-strategy images (STRATEGY_IMAGES), the eye-path
 * strategies of paths up to STRATEGY_MAX_EDGES edges get a record each, at naive_strategy_record
 * (after all the sums; numbered by strategy_index), and the sum holds only the longer ones. */
__kernel void bdpt_naive_connect(SCENE_PARAMS, const Camera cam, const int pool, const int splats, CONNECT_PARAMS)
{
    int gid = get_global_id(0);
    if (gid >= pool) return;
    SceneView scene = SCENE_INIT;
    int slot = gid;
    BdptSlot sample = slots[slot];
    int connections = 0, steps = 0;
#if STRATEGY_IMAGES
    for (int strategy = 0; strategy < STRATEGY_COUNT; ++strategy)   /* a strategy without a path: no record */
        record_pixel[naive_strategy_record(splats, pool, gid, strategy, STRATEGY_COUNT)] = -1;
#endif
    record_pixel[naive_sum_record(splats, gid)] = -1;   /* a slot not connecting: no record */
    if (sample.live == SLOT_CONNECTING) {   /* otherwise still walking, waiting or idle: nothing to connect */
        int n_eye = sample.eye_vertices, n_light = sample.light_vertices;
        int own_pixel = sample.pixel;
        __global const BdptVertex* eye = eye_vertices + vertex_index(slot, 0);
        __global const BdptVertex* light = light_vertices + vertex_index(slot, 0);
        connections = connection_count(n_light, n_eye);
        float3 sum = (float3)(0.0f);
        for (int k = 0; k < connections; ++k) {
            int s_len, t_len;
            connection_strategy(k, n_light, &s_len, &t_len);
            Connection c = connect_strategy(&scene, &cam, eye, light, s_len, t_len, own_pixel, &steps);
            if (t_len == 1) {     /* every splat has its record: pixel -1 where it reaches no pixel */
                int at = naive_splat_record(firsts[gid], s_len);
                record_value[at] = connection_record(&c);
                record_pixel[at] = c.pixel;
                continue;
            }
            if (c.pixel < 0) continue;
#if STRATEGY_IMAGES
            int strategy = strategy_index(s_len, t_len, STRATEGY_MAX_EDGES);
            if (strategy < STRATEGY_COUNT) {
                int at = naive_strategy_record(splats, pool, gid, strategy, STRATEGY_COUNT);
                record_value[at] = connection_record(&c);
                record_pixel[at] = own_pixel;
                continue;
            }
#endif
            sum += c.value;
        }
        /* .w: the weight by which the host multiplies .xyz; 1 for a sum of weighted values */
        record_value[naive_sum_record(splats, gid)] = (float4)(sum, STRATEGY_IMAGES ? 1.0f : 0.0f);
        record_pixel[naive_sum_record(splats, gid)] = own_pixel;
    }
#if COUNT_SIMD
    LaneCounts lane = {.work = connections, .shadow_rays = 0, .shadow_steps = steps};
    lane_counts[gid] = lane;
#endif
}
