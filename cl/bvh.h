/* BVH traversal for closest-hit and any-hit (shadow) queries.
 * Nodes are in depth-first order: the left child follows its parent, `first` is the right. */
#ifndef BVH_H
#define BVH_H

#include "scene.h"

#define BVH_STACK_SIZE 64

typedef struct {
    float t;      /* distance along the (unit) ray direction */
    float u, v;   /* barycentrics of v1 and v2 */
    int tri;      /* index into tris (leaf order), -1: miss */
} Hit;

/* Moller-Trumbore ray/triangle test; accepts t in (tmin, tmax). */
inline bool hit_triangle(__global const Triangle* tri, float3 o, float3 d, float tmin, float tmax,
                         float* t_out, float* u_out, float* v_out) {
    float3 e1 = tri->e1.xyz, e2 = tri->e2.xyz;
    float3 pv = cross(d, e2);
    float det = dot(e1, pv);
    if (det == 0.0f) return false;
    float inv = 1.0f / det;
    float3 tv = o - tri->v0.xyz;
    float u = dot(tv, pv) * inv;
    if (u < 0.0f || u > 1.0f) return false;
    float3 qv = cross(tv, e1);
    float v = dot(d, qv) * inv;
    if (v < 0.0f || u + v > 1.0f) return false;
    float t = dot(e2, qv) * inv;
    if (!(t > tmin && t < tmax)) return false;
    *t_out = t; *u_out = u; *v_out = v;
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
                if (hit_triangle(&s->tris[i], o, d, tmin, hit.t, &t, &u, &v)) {
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
                if (hit_triangle(&s->tris[i], o, d, tmin, tmax, &t, &u, &v)) { blocked = true; break; }
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
