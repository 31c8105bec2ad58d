/* The scene as the kernels see it: BVH nodes, triangles in leaf order, materials, lights.
 * Coordinates are relative to the scene's centre (the host subtracts it in float64), which
 * keeps float32 precision for scenes far from the origin. */
#ifndef SCENE_H
#define SCENE_H

#include "common.h"

/* A kernel takes the scene as SCENE_PARAMS and makes its view with `SceneView scene = SCENE_INIT;`
 * (both generated, with the host's argument order, from SCENE_ARGS in toolkit/core/layout.py). */

typedef struct {
    __global const BVH_WORD* nodes;   /* BvhNode records, or the wide BVH's words (BVH_WIDE, cl/bvh.h) */
    __global const Triangle* tris;
    __global const Material* materials;
    __global const LightTri* lights;
    int light_count;
    float epsilon;  /* ~1e-5 of the scene's size, set by the host */
} SceneView;

/* How far to move a ray origin off a surface: relative to the scene's size and to the
 * magnitude of the point's coordinates (float32 spacing grows with distance from the origin). */
HELPER float ray_offset(const SceneView* scene, float3 p) {
    float m = fmax(fabs(p.x), fmax(fabs(p.y), fabs(p.z)));
    return scene->epsilon + m * RAY_OFFSET_ULPS * FLT_EPSILON;   /* RAY_OFFSET_ULPS: layout.h */
}

/* p moved off the surface with normal n to the side of direction w. */
HELPER float3 offset_point(const SceneView* scene, float3 p, float3 n, float3 w) {
    float e = ray_offset(scene, p);
    return p + (dot(n, w) >= 0.0f ? e : -e) * n;
}

HELPER float3 triangle_normal(const Triangle* t) {
    return normalize(cross(t->v1.xyz - t->v0.xyz, t->v2.xyz - t->v0.xyz));
}

#endif
