/* Plain ray casting through the BVH, one ray per work-item: the device side of the
 * cross-check against Embree (toolkit/verify/crosscheck.py) and of `bench --peer embree`. Rays are in
 * the scene's rebased coordinates; directions are unit vectors; hits are reported with the
 * ORIGINAL scene triangle index (tris[i].prim), -1 on a miss. Rays come as the host's (n, 3)
 * float32 arrays and results go back as one buffer of one row per field, so the host neither
 * packs nor unpacks them (toolkit/opencl/raycast.py). n is below 2^29 (the host checks), so 3 * n + gid fits an int. */
#include "bvh.h"

/* The rays of both kernels: n of them, row gid of the host's (n, 3) float32 arrays. */
#define RAYS const int n, __global const float* origins, __global const float* dirs

/* Closest hit in (0, inf), as four rows of n words in `out`: t, u, v and the triangle (prim, as
 * an int); t = INFINITY and prim = -1 on a miss. One buffer, so the host reads it back at once. */
__kernel void raycast_closest(SCENE_PARAMS, RAYS, __global float* out)
{
    int gid = get_global_id(0);
    if (gid >= n) return;
    SceneView scene = SCENE_INIT;
    Hit h = trace_closest(&scene, vload3(gid, origins), vload3(gid, dirs), 0.0f, INFINITY, 0);   /* 0: no step count */
    bool hit = h.tri >= 0;
    out[gid] = hit ? h.t : INFINITY;
    out[n + gid] = hit ? h.u : 0.0f;
    out[2 * n + gid] = hit ? h.v : 0.0f;
    ((__global int*)out)[3 * n + gid] = hit ? scene.tris[h.tri].prim : -1;
}

/* Any hit on the segment (0, tmax[i]): blocked[i] = 1 if something lies on it, else 0. */
__kernel void raycast_any(SCENE_PARAMS, RAYS, __global const float* tmax, __global int* blocked)
{
    int gid = get_global_id(0);
    if (gid >= n) return;
    SceneView scene = SCENE_INIT;
    blocked[gid] = trace_any(&scene, vload3(gid, origins), vload3(gid, dirs), 0.0f, tmax[gid], 0) ? 1 : 0;
}
