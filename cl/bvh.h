/* BVH traversal for closest-hit and any-hit (shadow) queries.
 * Nodes are in depth-first order: the left child follows its parent, `first` is the right. */
#ifndef BVH_H
#define BVH_H

#include "scene.h"

/* BVH_STACK_SIZE comes from toolkit/layout.py (the host refuses deeper BVHs). */

typedef struct {
    float t;      /* distance along the (unit) ray direction */
    float u, v;   /* barycentrics of v1 and v2 */
    int tri;      /* index into tris (leaf order), -1: miss */
} Hit;

/* Watertight ray/triangle test (Woop, Benthin and Wald 2013, "Watertight Ray/Triangle
 * Intersection"): shear and scale space so the ray runs along +z from the origin, then decide
 * with 2D edge functions. Two triangles that share an edge evaluate that edge's function from
 * the same numbers with opposite sign, so a ray can never slip between them (Moller-Trumbore
 * can, on the shared edge). No fused multiply-add here: it would break that symmetry. */
#pragma OPENCL FP_CONTRACT OFF

typedef struct {
    int kx, ky, kz;        /* axis permutation: kz is the ray's largest direction component */
    float sx, sy, sz;      /* shear and scale */
} RayShear;

inline float axis(float3 v, int k) { return k == 0 ? v.x : (k == 1 ? v.y : v.z); }

inline RayShear ray_shear(float3 d) {
    float ax = fabs(d.x), ay = fabs(d.y), az = fabs(d.z);
    int kz = ax > ay ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2);
    int kx = kz == 2 ? 0 : kz + 1;
    int ky = kx == 2 ? 0 : kx + 1;
    float dz = axis(d, kz);
    if (dz < 0.0f) { int swap = kx; kx = ky; ky = swap; }   /* keep the winding */
    RayShear r = {kx, ky, kz, axis(d, kx) / dz, axis(d, ky) / dz, 1.0f / dz};
    return r;
}

/* Accepts t in (tmin, tmax); u, v are the barycentrics of v1 and v2. */
inline bool hit_triangle(__global const Triangle* tri, float3 o, const RayShear* r, float tmin, float tmax,
                         float* t_out, float* u_out, float* v_out) {
    float3 a = tri->v0.xyz - o, b = tri->v1.xyz - o, c = tri->v2.xyz - o;
    float az = axis(a, r->kz), bz = axis(b, r->kz), cz = axis(c, r->kz);
    float ax = axis(a, r->kx) - r->sx * az, ay = axis(a, r->ky) - r->sy * az;
    float bx = axis(b, r->kx) - r->sx * bz, by = axis(b, r->ky) - r->sy * bz;
    float cx = axis(c, r->kx) - r->sx * cz, cy = axis(c, r->ky) - r->sy * cz;
    float eu = cx * by - cy * bx;     /* edge functions: weights of v0, v1, v2 */
    float ev = ax * cy - ay * cx;
    float ew = bx * ay - by * ax;
    if ((eu < 0.0f || ev < 0.0f || ew < 0.0f) && (eu > 0.0f || ev > 0.0f || ew > 0.0f)) return false;
    float det = eu + ev + ew;
    if (det == 0.0f) return false;
    float inv = 1.0f / det;
    float t = r->sz * (eu * az + ev * bz + ew * cz) * inv;
    if (!(t > tmin && t < tmax)) return false;
    *t_out = t; *u_out = ev * inv; *v_out = ew * inv;
    return true;
}

/* Entry distance of the ray into the box, or INFINITY if it misses within (tmin, tmax). */
inline float hit_box(__global const BvhNode* node, float3 o, float3 inv_d, float tmin, float tmax) {
    float3 t0 = (node->lo.xyz - o) * inv_d;
    float3 t1 = (node->hi.xyz - o) * inv_d;
    float3 near = fmin(t0, t1), far = fmax(t0, t1);
    float enter = fmax(tmin, fmax(near.x, fmax(near.y, near.z)));
    float leave = fmin(tmax, fmin(far.x, fmin(far.y, far.z)));
    return enter <= leave ? enter : INFINITY;
}

/* Closest hit in (tmin, tmax). `steps` counts visited nodes (traversal divergence counter). */
inline Hit trace_closest(const SceneView* s, float3 o, float3 d, float tmin, float tmax, int* steps) {
    Hit hit = {tmax, 0.0f, 0.0f, -1};
    float3 inv_d = 1.0f / d;
    RayShear shear = ray_shear(d);
    int stack[BVH_STACK_SIZE];
    int top = 0;
    int node = 0;
    int visited = 0;
    for (;;) {
        __global const BvhNode* n = &s->nodes[node];
        ++visited;
        if (n->count > 0) {
            for (int i = n->first; i < n->first + n->count; ++i) {
                float t, u, v;
                if (hit_triangle(&s->tris[i], o, &shear, tmin, hit.t, &t, &u, &v)) {
                    hit.t = t; hit.u = u; hit.v = v; hit.tri = i;
                }
            }
        } else {
            int left = node + 1, right = n->first;
            float tl = hit_box(&s->nodes[left], o, inv_d, tmin, hit.t);
            float tr = hit_box(&s->nodes[right], o, inv_d, tmin, hit.t);
            if (tl != INFINITY && tr != INFINITY) {
                /* Visit the nearer child first, keep the other for later. */
                int first = tl <= tr ? left : right;
                stack[top++] = tl <= tr ? right : left;
                node = first;
                continue;
            }
            if (tl != INFINITY) { node = left; continue; }
            if (tr != INFINITY) { node = right; continue; }
        }
        /* Pop until a node that the ray still reaches before the current closest hit. */
        bool found = false;
        while (top > 0) {
            node = stack[--top];
            if (hit_box(&s->nodes[node], o, inv_d, tmin, hit.t) != INFINITY) { found = true; break; }
        }
        if (!found) break;
    }
    if (steps) *steps += visited;
    return hit;
}

/* Whether anything lies on the segment (tmin, tmax): shadow rays stop at the first hit. */
inline bool trace_any(const SceneView* s, float3 o, float3 d, float tmin, float tmax, int* steps) {
    float3 inv_d = 1.0f / d;
    RayShear shear = ray_shear(d);
    int stack[BVH_STACK_SIZE];
    int top = 0;
    int visited = 0;
    bool blocked = false;
    stack[top++] = 0;
    while (top > 0 && !blocked) {
        int node = stack[--top];
        __global const BvhNode* n = &s->nodes[node];
        ++visited;
        if (hit_box(n, o, inv_d, tmin, tmax) == INFINITY) continue;
        if (n->count > 0) {
            for (int i = n->first; i < n->first + n->count; ++i) {
                float t, u, v;
                if (hit_triangle(&s->tris[i], o, &shear, tmin, tmax, &t, &u, &v)) { blocked = true; break; }
            }
        } else {
            stack[top++] = n->first;
            stack[top++] = node + 1;
        }
    }
    if (steps) *steps += visited;
    return blocked;
}

#endif
