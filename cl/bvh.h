/* BVH traversal for closest-hit and any-hit (shadow) queries, for one of two BVHs chosen at
 * compile time (toolkit/opencl/device_scene.py, `--bvh`):
 * - binary (default without BVH_WIDE): nodes in depth-first order, the left child follows its
 *   parent, `first` is the right; one box test per step, one triangle at a time.
 * - wide (BVH_WIDE): eight (or four, NODE_WIDTH) children per node and four triangles per leaf,
 *   each tested with float8 / float4 operations that the OpenCL compiler turns into SSE/AVX
 *   instructions. This is SIMD inside one ray (Embree's single-ray kernels work this way); the
 *   talk's streams are SIMD across rays (one ray per work-item). Both give the same hits: the
 *   same float operations run lane by lane, only the order of visiting differs. */
#ifndef BVH_H
#define BVH_H

#include "scene.h"

/* BVH_STACK_SIZE comes from toolkit/core/layout.py (the host refuses deeper BVHs). */

typedef struct {
    float t;      /* distance along the (unit) ray direction */
    float u, v;   /* barycentrics of v1 and v2 */
    int tri;      /* index into tris (leaf order), -1: miss */
} Hit;

/* Watertight ray/triangle test (Woop, Benthin and Wald 2013, "Watertight Ray/Triangle
 * Intersection"): shear and scale space so the ray runs along +z from the origin, then decide
 * with 2D edge functions. Two triangles that share an edge evaluate that edge's function from
 * the same numbers with opposite sign, so a ray can never slip between them (Moller-Trumbore
 * can, on the shared edge). No fused multiply-add here: it would break that symmetry, so the
 * test's body (and the wide BVH's four-lane copy, hit_triangles) starts with
 * `#pragma OPENCL FP_CONTRACT OFF`. At the start of a compound statement the pragma holds to
 * the end of that block only (OpenCL C 6.10, as C99's STDC FP_CONTRACT), so all other code,
 * shading included, keeps whatever contraction the compiler chooses (fused multiply-add on
 * GPUs). tests/test_watertight.py fires rays at shared edges and vertices. */

typedef struct {
    int kx, ky, kz;        /* axis permutation: kz is the ray's largest direction component */
    float sx, sy, sz;      /* shear and scale */
} RayShear;

HELPER float axis(float3 v, int k) { return k == 0 ? v.x : (k == 1 ? v.y : v.z); }

HELPER RayShear ray_shear(float3 d) {
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
HELPER bool hit_triangle(__global const Triangle* tri, float3 o, const RayShear* r, float tmin, float tmax,
                         float* t_out, float* u_out, float* v_out) {
#pragma OPENCL FP_CONTRACT OFF
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

/* The next float above t >= 0 (nextafter(t, INFINITY)), written out for the same reason as
 * min4 below: PoCL's nextafter is a function call, and the leaf test asks for it every time. */
HELPER float next_up(float t) { return t < INFINITY ? as_float(as_int(t) + 1) : t; }

/* Whether a hit at t on triangle `tri` replaces `hit`: the closest hit is the smallest t and, on
 * equal t (coplanar overlapping triangles, a ray through a shared edge), the lowest triangle
 * index. So it does not depend on the order in which a BVH visits its leaves, and the binary
 * and wide BVHs report the same triangle. The search accepts t up to hit.t itself for this. */
HELPER bool closer(float t, int tri, const Hit* hit) {
    return t < hit->t || (t == hit->t && tri < hit->tri);
}

/* The box test must never cull a box whose triangle the triangle test hits: its distances are
 * rounded (the slab subtraction and product), and so is the triangle's t. A ray through a
 * triangle's edge on the box's face can then leave the box a few ulps before it reaches the
 * triangle. Widening the exit distance by BOX_SLACK (relative) keeps the test conservative
 * (pbrt-v3 section 3.9.2 widens tMax by 1 + 2 gamma(3); we allow the triangle's rounding too).
 * A box entered at the current closest hit is still visited: it may hold an equal-t tie. */
#define BOX_SLACK (1.0f + 16.0f * FLT_EPSILON)

/* Entry distance of the ray into the box, or INFINITY if it misses within (tmin, tmax). */
HELPER float hit_box(__global const BvhNode* node, float3 o, float3 inv_d, float tmin, float tmax) {
    float3 t0 = (node->lo.xyz - o) * inv_d;
    float3 t1 = (node->hi.xyz - o) * inv_d;
    float3 near = fmin(t0, t1), far = fmax(t0, t1);
    float enter = fmax(tmin, fmax(near.x, fmax(near.y, near.z)));
    float leave = fmin(tmax, fmin(far.x, fmin(far.y, far.z))) * BOX_SLACK;
    return enter <= leave ? enter : INFINITY;
}

#ifndef BVH_WIDE

/* Closest hit in (tmin, tmax). `steps` counts visited nodes (traversal divergence counter). */
HELPER Hit trace_closest(const SceneView* scene, float3 o, float3 d, float tmin, float tmax, int* steps) {
    Hit hit = {tmax, 0.0f, 0.0f, -1};
    float3 inv_d = 1.0f / d;
    RayShear shear = ray_shear(d);
    int stack[BVH_STACK_SIZE];
    int top = 0;
    int node = 0;
    int visited = 0;
    for (;;) {
        __global const BvhNode* n = &scene->nodes[node];
        ++visited;
        if (n->count > 0) {
            for (int i = n->first; i < n->first + n->count; ++i) {
                float t, u, v;
                if (hit_triangle(&scene->tris[i], o, &shear, tmin, next_up(hit.t), &t, &u, &v)
                    && closer(t, i, &hit)) {
                    hit.t = t; hit.u = u; hit.v = v; hit.tri = i;
                }
            }
        } else {
            int left = node + 1, right = n->first;
            float tl = hit_box(&scene->nodes[left], o, inv_d, tmin, hit.t);
            float tr = hit_box(&scene->nodes[right], o, inv_d, tmin, hit.t);
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
            if (hit_box(&scene->nodes[node], o, inv_d, tmin, hit.t) != INFINITY) { found = true; break; }
        }
        if (!found) break;
    }
    if (steps) *steps += visited;
    return hit;
}

/* Whether anything lies on the segment (tmin, tmax): shadow rays stop at the first hit. */
HELPER bool trace_any(const SceneView* scene, float3 o, float3 d, float tmin, float tmax, int* steps) {
    float3 inv_d = 1.0f / d;
    RayShear shear = ray_shear(d);
    int stack[BVH_STACK_SIZE];
    int top = 0;
    int visited = 0;
    bool blocked = false;
    stack[top++] = 0;
    while (top > 0 && !blocked) {
        int node = stack[--top];
        __global const BvhNode* n = &scene->nodes[node];
        ++visited;
        if (hit_box(n, o, inv_d, tmin, tmax) == INFINITY) continue;
        if (n->count > 0) {
            for (int i = n->first; i < n->first + n->count; ++i) {
                float t, u, v;
                if (hit_triangle(&scene->tris[i], o, &shear, tmin, tmax, &t, &u, &v)) { blocked = true; break; }
            }
        } else {
            stack[top++] = n->first;
            stack[top++] = node + 1;
        }
    }
    if (steps) *steps += visited;
    return blocked;
}

#else  /* BVH_WIDE */

/* The wide BVH lives in one buffer of 16-byte words (s->nodes): WideNode and TriGroup records
 * (toolkit/core/layout.py), found by their position. A child reference >= 0 is an inner node,
 * < 0 is ~position of a leaf's TriGroup, WIDE_EMPTY an unused lane. A node has NODE_WIDTH
 * children, held in vectors of that width; the host chooses it (toolkit/opencl/device_scene.py,
 * node_width): 8 (float8, one AVX register) where work-items are threads, 4 where they are lanes. */
#if NODE_WIDTH == 8
typedef WideNode8 WideNode;
typedef float8 floatN;
typedef int8 intN;
#elif NODE_WIDTH == 4
typedef WideNode4 WideNode;
typedef float4 floatN;
typedef int4 intN;
#else
#error "the wide BVH needs NODE_WIDTH 4 or 8 (DeviceScene.features)"
#endif

HELPER __global const WideNode* wide_node(const SceneView* scene, int ref) {
    return (__global const WideNode*)(scene->nodes + ref);
}
HELPER __global const TriGroup* tri_group(const SceneView* scene, int ref) {
    return (__global const TriGroup*)(scene->nodes + ~ref);
}
/* Coordinate k (0 x, 1 y, 2 z) of vertex v of the group's four triangles: v0x, v0y, v0z, v1x, ... follow each other. */
HELPER float4 tri_group_coord(__global const TriGroup* g, int v, int k) {
    return ((__global const float4*)g)[3 * v + k];
}
HELPER float lane(float4 v, int i) { return i == 0 ? v.s0 : (i == 1 ? v.s1 : (i == 2 ? v.s2 : v.s3)); }
HELPER int lane_int(int4 v, int i) { return i == 0 ? v.s0 : (i == 1 ? v.s1 : (i == 2 ? v.s2 : v.s3)); }

/* fmin, fmax and any of four lanes, written out: PoCL 3.0 does not inline its built-in
 * functions, so each fmin in the traversal's hottest loop was a function call (perf: fmin and
 * fmax 8% of pt_naive). Same results: fmin's other operand where one is NaN (a slab's
 * 0 * inf); a vector ?: picks lanes like select. tests/test_wide_bvh.py holds the hits. */
HELPER floatN minN(floatN a, floatN b) { return ((a < b) | (b != b)) ? a : b; }
HELPER floatN maxN(floatN a, floatN b) { return ((a > b) | (b != b)) ? a : b; }
HELPER bool any4(int4 m) { return (m.s0 | m.s1 | m.s2 | m.s3) < 0; }

/* hit_box for all children at once: entry distances, INFINITY where a child is missed (or the
 * lane is empty). The same operations as hit_box, lane by lane. */
HELPER floatN hit_boxes(__global const WideNode* n, float3 o, float3 inv_d, float tmin, float tmax) {
    floatN x0 = (n->lo_x - o.x) * inv_d.x, x1 = (n->hi_x - o.x) * inv_d.x;
    floatN y0 = (n->lo_y - o.y) * inv_d.y, y1 = (n->hi_y - o.y) * inv_d.y;
    floatN z0 = (n->lo_z - o.z) * inv_d.z, z1 = (n->hi_z - o.z) * inv_d.z;
    floatN enter = maxN((floatN)(tmin), maxN(minN(x0, x1), maxN(minN(y0, y1), minN(z0, z1))));
    floatN leave = minN((floatN)(tmax), minN(maxN(x0, x1), minN(maxN(y0, y1), maxN(z0, z1)))) * BOX_SLACK;
    intN hit = (enter <= leave) & (n->child != (intN)(WIDE_EMPTY));
    return hit ? enter : (floatN)(INFINITY);
}

/* hit_triangle for the four triangles of a group at once: the lanes with a hit in (tmin, tmax)
 * (a mask: -1 where hit) and their t, u, v. The same operations as hit_triangle, in the same
 * order, lane by lane (FP_CONTRACT off in both), so the two BVHs find bit-identical hits and
 * the watertight property holds in every lane. Empty lanes are degenerate triangles: det = 0. */
HELPER int4 hit_triangles(__global const TriGroup* g, float3 o, const RayShear* r, float tmin, float tmax,
                          float4* t_out, float4* u_out, float4* v_out) {
#pragma OPENCL FP_CONTRACT OFF
    float ox = axis(o, r->kx), oy = axis(o, r->ky), oz = axis(o, r->kz);
    float4 az = tri_group_coord(g, 0, r->kz) - oz;
    float4 bz = tri_group_coord(g, 1, r->kz) - oz;
    float4 cz = tri_group_coord(g, 2, r->kz) - oz;
    float4 ax = (tri_group_coord(g, 0, r->kx) - ox) - r->sx * az, ay = (tri_group_coord(g, 0, r->ky) - oy) - r->sy * az;
    float4 bx = (tri_group_coord(g, 1, r->kx) - ox) - r->sx * bz, by = (tri_group_coord(g, 1, r->ky) - oy) - r->sy * bz;
    float4 cx = (tri_group_coord(g, 2, r->kx) - ox) - r->sx * cz, cy = (tri_group_coord(g, 2, r->ky) - oy) - r->sy * cz;
    float4 eu = cx * by - cy * bx;
    float4 ev = ax * cy - ay * cx;
    float4 ew = bx * ay - by * ax;
    float4 zero = (float4)(0.0f);
    int4 mixed = ((eu < zero) | (ev < zero) | (ew < zero)) & ((eu > zero) | (ev > zero) | (ew > zero));
    float4 det = eu + ev + ew;
    float4 inv = 1.0f / det;
    float4 t = r->sz * (eu * az + ev * bz + ew * cz) * inv;
    *t_out = t; *u_out = ev * inv; *v_out = ew * inv;
    return ~mixed & (det != zero) & (t > (float4)(tmin)) & (t < (float4)(tmax));
}

/* descend(stack_ref, stack_t, &top, child, enter): the nearest child that a node's box test hit
 * (WIDE_EMPTY if none), the other hit children pushed onto the stack, nearest on top, so they
 * are visited front to back (a close hit culls the boxes behind it). One way for each width,
 * each the faster where that width is used. */
#if NODE_WIDTH == 4
/* One compare-and-swap of a sorting network: afterwards (ta, ra) is the nearer entry. */
HELPER void order_pair(float* ta, int* ra, float* tb, int* rb) {
    bool swap = *tb < *ta;
    float t = *ta; int r = *ra;
    *ta = swap ? *tb : *ta; *ra = swap ? *rb : *ra;
    *tb = swap ? t : *tb;   *rb = swap ? r : *rb;
}

/* Four children, where work-items run as SIMD lanes: written without branches or loops that
 * depend on the ray. With lanes (Intel's CPU runtime with lanes on), each store whose address
 * or condition differs between lanes becomes a masked scatter, a test and a branch per lane,
 * and an insertion sort with a data-dependent loop did that per shift (the kernel's build
 * remarks counted 15 scatters). Here a five-step sorting network orders the four entry
 * distances (misses are INFINITY, so they sort last), and all four entries are stored
 * unconditionally in [top, top + 4): the `hits` nearest ones reversed at the bottom, nearest
 * on top, the misses above them, where the next push overwrites them (the stack has room for
 * that: BVH_STACK_SLACK). */
#define BVH_STACK_SLACK (NODE_WIDTH - 1)
HELPER int push_hit_children(int* stack_ref, float* stack_t, int top, int4 child, float4 enter) {
    float t0 = enter.s0, t1 = enter.s1, t2 = enter.s2, t3 = enter.s3;
    int r0 = child.s0, r1 = child.s1, r2 = child.s2, r3 = child.s3;
    order_pair(&t0, &r0, &t1, &r1); order_pair(&t2, &r2, &t3, &r3);
    order_pair(&t0, &r0, &t2, &r2); order_pair(&t1, &r1, &t3, &r3);
    order_pair(&t1, &r1, &t2, &r2);                   /* now t0 <= t1 <= t2 <= t3 */
    int hits = (t0 != INFINITY) + (t1 != INFINITY) + (t2 != INFINITY) + (t3 != INFINITY);
    /* Entry k (k-th nearest) goes to top + hits - 1 - k if it is a hit, else to top + k. */
    int p0 = hits > 0 ? top + hits - 1 : top;
    int p1 = hits > 1 ? top + hits - 2 : top + 1;
    int p2 = hits > 2 ? top + hits - 3 : top + 2;
    int p3 = hits > 3 ? top : top + 3;
    stack_ref[p0] = r0; stack_t[p0] = t0;
    stack_ref[p1] = r1; stack_t[p1] = t1;
    stack_ref[p2] = r2; stack_t[p2] = t2;
    stack_ref[p3] = r3; stack_t[p3] = t3;
    return top + hits;
}

/* The nearest child hit, the others pushed (nearest on top); WIDE_EMPTY if none was hit. */
HELPER int descend(int* stack_ref, float* stack_t, int* top, int4 child, float4 enter) {
    int below = *top;
    *top = push_hit_children(stack_ref, stack_t, *top, child, enter);
    return *top == below ? WIDE_EMPTY : stack_ref[--*top];
}

#else
/* Eight children, where each work-item is a thread: a branch costs a thread little, so the
 * common cases take their own short way (Embree's single-ray traversal does the same). Most
 * nodes have one or two of their eight children hit (surface rays on cornell_spheres: 1.5), so
 * with one the ray goes straight on, with two one compare decides which waits on the stack, and
 * only three or more are sorted. The loop over all eight lanes that this replaced, a test for
 * a hit in each, held a fifth of pt_naive_render's perf samples on cornell_spheres; this way,
 * rays from that scene's surfaces run 25% faster (results/issue22_lanes.md). */
#define BVH_STACK_SLACK 0

/* Bit i set where child i was hit (entry distance not INFINITY). */
HELPER uint hit_bits(float8 enter) {
    int8 bit = (enter != (float8)(INFINITY)) & (int8)(1, 2, 4, 8, 16, 32, 64, 128);
    return (uint)(bit.s0 | bit.s1 | bit.s2 | bit.s3 | bit.s4 | bit.s5 | bit.s6 | bit.s7);
}

/* Index of the lowest set bit of x != 0. */
HELPER int lowest_bit(uint x) {
#if BUILTINS_ARE_CALLS
    return __builtin_ctz(x);   /* PoCL would call its ctz/clz; clang's built-in is one instruction */
#else
    return 31 - clz(x & (0u - x));
#endif
}

/* A child (ref, entry distance t) onto the stack, kept sorted from `bottom` up: nearest on top. */
HELPER void insert_sorted(int* stack_ref, float* stack_t, int bottom, int* top, int ref, float t) {
    int j = (*top)++;
    for (; j > bottom && stack_t[j - 1] < t; --j) {   /* the farther ones stay below */
        stack_t[j] = stack_t[j - 1]; stack_ref[j] = stack_ref[j - 1];
    }
    stack_t[j] = t; stack_ref[j] = ref;
}

HELPER int descend(int* stack_ref, float* stack_t, int* top, int8 child, float8 enter) {
    uint bits = hit_bits(enter);
    if (bits == 0) return WIDE_EMPTY;
    float t[NODE_WIDTH];
    int ref[NODE_WIDTH];
    vstore8(enter, 0, t);
    vstore8(child, 0, ref);
    int a = lowest_bit(bits);
    bits &= bits - 1;
    if (bits == 0) return ref[a];                   /* one child hit: straight on */
    int b = lowest_bit(bits);
    bits &= bits - 1;
    if (bits == 0) {                                /* two: the farther one waits */
        bool b_nearer = t[b] < t[a];
        int near = b_nearer ? b : a, far = b_nearer ? a : b;
        stack_ref[*top] = ref[far]; stack_t[*top] = t[far]; ++*top;
        return ref[near];
    }
    int bottom = *top;                              /* three or more: sorted onto the stack */
    insert_sorted(stack_ref, stack_t, bottom, top, ref[a], t[a]);
    insert_sorted(stack_ref, stack_t, bottom, top, ref[b], t[b]);
    for (; bits != 0; bits &= bits - 1) {
        int i = lowest_bit(bits);
        insert_sorted(stack_ref, stack_t, bottom, top, ref[i], t[i]);
    }
    --*top;
    return stack_ref[*top];
}
#endif

/* Closest hit in (tmin, tmax). `steps` counts visited nodes and leaves (traversal divergence counter). */
HELPER Hit trace_closest(const SceneView* scene, float3 o, float3 d, float tmin, float tmax, int* steps) {
    Hit hit = {tmax, 0.0f, 0.0f, -1};
    float3 inv_d = 1.0f / d;
    RayShear shear = ray_shear(d);
    int stack_ref[BVH_STACK_SIZE + BVH_STACK_SLACK];
    float stack_t[BVH_STACK_SIZE + BVH_STACK_SLACK];
    int top = 0;
    int visited = 0;
    stack_ref[top] = 0; stack_t[top] = tmin; ++top;   /* the root */
    while (top > 0) {
        --top;
        if (stack_t[top] > hit.t * BOX_SLACK) continue;   /* entered beyond the closest hit so far */
        int ref = stack_ref[top];
        ++visited;
        /* Inner nodes, one after another: on to the nearest child hit straight away (it was hit
         * before hit.t, so it needs no cull test), then a leaf. The "while-while" loop of Aila
         * and Laine (2009): where work-items are SIMD lanes, lanes that are all on inner nodes
         * step together instead of waiting for each other's leaf tests. */
        while (ref >= 0) {
            __global const WideNode* n = wide_node(scene, ref);
            ref = descend(stack_ref, stack_t, &top, n->child, hit_boxes(n, o, inv_d, tmin, hit.t));
            if (ref == WIDE_EMPTY) break;
            ++visited;
        }
        if (ref != WIDE_EMPTY) {   /* a leaf */
            __global const TriGroup* g = tri_group(scene, ref);
            float4 t, u, v;
            int4 mask = hit_triangles(g, o, &shear, tmin, next_up(hit.t), &t, &u, &v);
            if (any4(mask)) {
                /* The nearest lane; on equal distances the first (lanes hold increasing triangle indices). */
                t = mask ? t : (float4)(INFINITY);
                float best = fmin(fmin(t.s0, t.s1), fmin(t.s2, t.s3));
                int i = t.s0 == best ? 0 : (t.s1 == best ? 1 : (t.s2 == best ? 2 : 3));
                int tri = lane_int(g->tri, i);
                if (closer(best, tri, &hit)) {
                    hit.t = best; hit.u = lane(u, i); hit.v = lane(v, i); hit.tri = tri;
                }
            }
        }
    }
    if (steps) *steps += visited;
    return hit;
}

/* Whether anything lies on the segment (tmin, tmax): shadow rays stop at the first hit. */
HELPER bool trace_any(const SceneView* scene, float3 o, float3 d, float tmin, float tmax, int* steps) {
    float3 inv_d = 1.0f / d;
    RayShear shear = ray_shear(d);
    int stack_ref[BVH_STACK_SIZE + BVH_STACK_SLACK];
    float stack_t[BVH_STACK_SIZE + BVH_STACK_SLACK];
    int top = 0;
    int visited = 0;
    bool blocked = false;
    stack_ref[top] = 0; stack_t[top] = tmin; ++top;
    while (top > 0 && !blocked) {
        int ref = stack_ref[--top];
        ++visited;
        while (ref >= 0) {      /* inner nodes, as in trace_closest */
            __global const WideNode* n = wide_node(scene, ref);
            ref = descend(stack_ref, stack_t, &top, n->child, hit_boxes(n, o, inv_d, tmin, tmax));
            if (ref == WIDE_EMPTY) break;
            ++visited;
        }
        if (ref != WIDE_EMPTY) {
            float4 t, u, v;
            blocked = any4(hit_triangles(tri_group(scene, ref), o, &shear, tmin, tmax, &t, &u, &v));
        }
    }
    if (steps) *steps += visited;
    return blocked;
}

#endif /* BVH_WIDE */

#endif
