/* Plain ray casting through the BVH, one ray per work-item: the device side of the
 * cross-check against Embree (toolkit/crosscheck.py). Rays are in the scene's rebased
 * coordinates; directions are unit vectors; hits are reported with the ORIGINAL scene
 * triangle index (tris[i].prim), -1 on a miss. */
#include "bvh.h"

/* Closest hit in (0, inf): out[i] = (t, u, v, 0) and prim[i]; t = INFINITY on a miss. */
__kernel void raycast_closest(SCENE_PARAMS, const int n,
                              __global const float4* origins,
                              __global const float4* dirs,
                              __global float4* out,
                              __global int* prim)
{
    int gid = get_global_id(0);
    if (gid >= n) return;
    SceneView s = SCENE_INIT;
    int steps = 0;
    Hit h = trace_closest(&s, origins[gid].xyz, dirs[gid].xyz, 0.0f, INFINITY, &steps);
    if (h.tri < 0) {
        out[gid] = (float4)(INFINITY, 0.0f, 0.0f, 0.0f);
        prim[gid] = -1;
    } else {
        out[gid] = (float4)(h.t, h.u, h.v, 0.0f);
        prim[gid] = s.tris[h.tri].prim;
    }
}

/* Any hit on the segment (0, dirs[i].w): blocked[i] = 1 if something lies on it, else 0. */
__kernel void raycast_any(SCENE_PARAMS, const int n,
                          __global const float4* origins,
                          __global const float4* dirs,
                          __global int* blocked)
{
    int gid = get_global_id(0);
    if (gid >= n) return;
    SceneView s = SCENE_INIT;
    int steps = 0;
    float4 d = dirs[gid];
    blocked[gid] = trace_any(&s, origins[gid].xyz, d.xyz, 0.0f, d.w, &steps) ? 1 : 0;
}
