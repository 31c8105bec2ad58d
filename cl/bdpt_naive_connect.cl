/* BDPT, connect phase the plain way: the work-item of each sample slot loops over all the
 * (s, t) strategies of its sample if it has terminated, and idles otherwise. The number of
 * strategies grows with the product of the two subpath lengths, so the lanes of a warp wait
 * for the sample with the longest paths, and lanes whose sample is still walking wait too
 * (the talk: ~17% active threads). The random walk is shared with bdpt_parallel_connect
 * (bdpt_walk.h). */
#include "bdpt_walk.h"

/* Records: for pool slot k, the t = 1 splats at k * MAX_VERTICES + (s - 1), and the sum of
 * its eye-path strategies at pool * MAX_VERTICES + k (pixel -1: nothing; the host pre-fills). */
__kernel void bdpt_naive_connect(SCENE_PARAMS, const Camera cam, const int pool, __global const int* live,
                                 __global const BdptVertex* eye_vertices, __global const BdptVertex* light_vertices,
                                 __global const int* eye_vertex_count, __global const int* light_vertex_count,
                                 __global const int* sample_ids,
                                 __global float4* record_value, __global int* record_pixel,
                                 __global int4* lane_counts)
{
    int gid = get_global_id(0);
    if (gid >= pool) return;
    SceneView s = SCENE_INIT;
    int slot = gid;
    if (live[slot] != 0) {   /* still walking (or idle): nothing to connect */
#if COUNT_SIMD
        lane_counts[gid] = (int4)(0);
#endif
        return;
    }
    int n_eye = eye_vertex_count[slot], n_light = light_vertex_count[slot];
    int own_pixel = sample_ids[slot] % (cam.width * cam.height);
    __global const BdptVertex* eye = eye_vertices + vertex_index(slot, 0);
    __global const BdptVertex* light = light_vertices + vertex_index(slot, 0);
    int connections = connection_count(n_light, n_eye);
    int steps = 0;
    float3 sum = (float3)(0.0f);
    for (int k = 0; k < connections; ++k) {
        int s_len, t_len;
        connection_strategy(k, n_light, &s_len, &t_len);
        Connection c = connect_strategy(&s, &cam, eye, light, s_len, t_len, own_pixel, &steps);
        if (c.pixel < 0) continue;
        if (t_len == 1) {
            record_value[gid * MAX_VERTICES + s_len - 1] = (float4)(c.value, c.weight);
            record_pixel[gid * MAX_VERTICES + s_len - 1] = c.pixel;
        } else {
            sum += c.value;
        }
    }
    record_value[pool * MAX_VERTICES + gid] = (float4)(sum, 0.0f);
    record_pixel[pool * MAX_VERTICES + gid] = own_pixel;
#if COUNT_SIMD
    lane_counts[gid] = (int4)(connections, steps, 0, 0);
#endif
}
