/* One path-tracing step, shared by every path tracer: start a path at the camera, and extend
 * it by one vertex (intersect, add emission, next-event estimation, sample the BSDF, Russian
 * roulette). The techniques differ only in how they schedule these steps over work-items. */
#ifndef PATH_H
#define PATH_H

#include "common.h"
#include "philox.h"
#include "camera.h"
#include "bvh.h"
#include "lights.h"
#include "materials.h"

/* Per-lane work counters for the SIMD-efficiency model (all zero unless the host reads them). */
typedef struct {
    int traversal_steps;   /* BVH nodes visited by closest-hit rays */
    int shadow_steps;      /* BVH nodes visited by shadow rays */
    int shadow_rays;
} LaneCounters;

/* What a lane did in one launch, as the host reads it (LaneCounts, toolkit/core/layout.py). */
HELPER LaneCounts lane_counts_of(int work, const LaneCounters* c) {
    LaneCounts out = {.work = work, .closest_steps = c->traversal_steps, .shadow_rays = c->shadow_rays,
                      .shadow_steps = c->shadow_steps};
    return out;
}

/* A new camera path for (pixel, sample): the camera sample (camera.h) of its first two dimensions.
 * `slot` is where its result goes in the pass's output buffer. */
HELPER void path_start(PathState* p, const Camera* cam, int pixel, int sample, int slot, uint seed) {
    Sampler rng = sampler_init(seed, (uint)pixel, (uint)sample);
    p->origin = (float4)(cam->origin.xyz, 0.0f);   /* camera rays start exactly at the pinhole */
    p->dir = (float4)(camera_sample(cam, pixel, sampler_get(&rng, DIM_PIXEL), sampler_get(&rng, DIM_PIXEL + 1)), 0.0f);
    p->throughput = (float4)(1.0f, 1.0f, 1.0f, 0.0f);
    p->radiance = (float4)(0.0f);
    p->prev_pdf = 0.0f;
    p->prev_specular = 1;   /* nothing to MIS against for emitters seen directly */
    p->bounce = 0;
    p->pixel = pixel;
    p->sample = sample;
    p->slot = slot;
}

/* The sample with index `id` in a pass (sample_pixel, camera.h); its result goes to output slot id. */
HELPER void path_start_sample(PathState* p, const Camera* cam, int id, int sample_base, uint seed) {
    path_start(p, cam, sample_pixel(cam, id), sample_number(cam, id, sample_base), id, seed);
}

HELPER float path_rand(const PathState* p, Sampler* rng, uint offset) {
    return sampler_get(rng, bounce_dim(p->bounce, offset));
}

/* Emission found by the BSDF-sampled ray (hit at distance t, from direction wo), MIS-weighted
 * against light sampling (Veach 1997, sec. 9.2); after the camera or a specular bounce light
 * sampling was impossible. */
HELPER void path_add_emission(const SceneView* scene, PathState* p, const Triangle* tri, float3 ng, float3 wo,
                              float t) {
    float3 le = emitted(scene, tri, ng, wo);
    if (!is_black(le)) {
        float w = 1.0f;
        if (!p->prev_specular) {
            float light_pdf = tri->light_pdf * t * t / fabs(dot(ng, wo));
            w = power_heuristic(p->prev_pdf, light_pdf);
        }
        p->radiance.xyz += p->throughput.xyz * le * w;
    }
}

/* Next-event estimation at x (geometric normal ng, shading frame ts, tt, n): one point on a
 * light, one shadow ray, MIS with BSDF sampling. The shadow ray is only prepared here
 * (shadow->slot >= 0 if there is one); the caller traces it now or queues it. */
HELPER void path_prepare_shadow_ray(const SceneView* scene, const PathState* p, Sampler* rng, const Material* m,
                                    float3 x, float3 ng, float3 ts, float3 tt, float3 n, float3 wo_local,
                                    ShadowRay* shadow) {
    LightSample ls = sample_light(scene, path_rand(p, rng, DIM_LIGHT_PICK),
                                  path_rand(p, rng, DIM_LIGHT_U), path_rand(p, rng, DIM_LIGHT_V));
    float3 to_light = ls.p - x;
    float dist2 = dot(to_light, to_light);
    float3 wi = to_light * rsqrt(dist2);
    float cos_light = dot(ls.n, -wi);
    if (!(cos_light > 0.0f && dist2 > 0.0f)) return;
    float3 wi_local = to_local(wi, ts, tt, n);
    float bsdf_pdf;
    float3 f = bsdf_eval(m, wo_local, wi_local, &bsdf_pdf);
    if (is_black(f)) return;
    float light_pdf = ls.pdf_area * dist2 / cos_light;
    float3 from = offset_point(scene, x, ng, wi);
    float3 to = offset_point(scene, ls.p, ls.n, -wi);
    float3 seg = to - from;
    float len = length(seg);
    if (dot(seg, wi) > 0.0f) {
        float w = power_heuristic(light_pdf, bsdf_pdf);
        shadow->origin = from;
        shadow->length = len;
        shadow->dir = (float4)(seg / len, 0.0f);
        shadow->contribution = (float4)(p->throughput.xyz * f * wi_local.z * ls.emission * (w / light_pdf), 0.0f);
        shadow->slot = p->slot;
    }
}

/* Continue the path from x by sampling the BSDF, then Russian roulette (common.h) from RR_DEPTH
 * bounces on. Returns false when the path has terminated. */
HELPER bool path_continue(const SceneView* scene, PathState* p, Sampler* rng, const Material* m,
                          float3 x, float3 ng, float3 ts, float3 tt, float3 n, float3 wo_local) {
    BsdfSample bs;
    if (!bsdf_sample(m, wo_local, path_rand(p, rng, DIM_BSDF_U), path_rand(p, rng, DIM_BSDF_V),
                     path_rand(p, rng, DIM_BSDF_LOBE), &bs))
        return false;
    float3 wi = to_world(bs.wi, ts, tt, n);
    p->throughput.xyz *= bs.weight;
    p->prev_pdf = bs.pdf;
    p->prev_specular = bs.specular ? 1 : 0;
    p->origin = (float4)(offset_point(scene, x, ng, wi), 0.0f);
    p->dir = (float4)(wi, 0.0f);
    p->bounce += 1;
#if USE_RUSSIAN_ROULETTE
    if (p->bounce >= RR_DEPTH) {
        float3 throughput = p->throughput.xyz;
        if (!roulette(&throughput, 1.0f, sampler_get(rng, bounce_dim(p->bounce - 1, DIM_ROULETTE)))) return false;
        p->throughput.xyz = throughput;
    }
#endif
    return !is_black(p->throughput.xyz);
}

/* The closest hit of the path's next ray (a miss where the path may take no more segments). */
HELPER HitRecord path_trace(const SceneView* scene, const PathState* p, LaneCounters* count) {
    HitRecord miss = {INFINITY, -1};
#if USE_MAX_DEPTH
    /* Only reached with max_depth 0 (longer limits end the path in path_shade_deferred): not even
     * the camera segment, so the image is black in every technique (FORMAT.md). */
    if (p->bounce >= MAX_DEPTH) return miss;
#endif
    Hit h = trace_closest(scene, p->origin.xyz, p->dir.xyz, 0.0f, INFINITY, &count->traversal_steps);
    if (h.tri < 0) return miss;
    HitRecord hit = {h.t, h.tri};
    return hit;
}

/* path_trace for entry i of a stream of paths, its hit stored at entry i of a stream of hits:
 * the trace kernels of the wavefront techniques (pt_compact_regen, extend_in_place.h). */
HELPER void path_trace_entry(const SceneView* scene, PathStateSoA paths, HitRecordSoA hits, int i,
                             LaneCounters* count) {
    PathState p = path_state_load(paths, i);
    HitRecord hit = path_trace(scene, &p, count);
    hit_record_store(hits, i, &hit);
}

/* Shade the vertex that the path's ray found (`hit`, from path_trace): add emission, prepare a
 * next-event shadow ray (shadow->slot >= 0 if there is one), sample the BSDF, roulette.
 * Returns false when the path has terminated. */
HELPER bool path_shade_deferred(const SceneView* scene, PathState* p, HitRecord hit, uint seed, ShadowRay* shadow) {
    shadow->slot = -1;
    if (hit.tri < 0) return false;                   /* left the scene: no environment light */
    Sampler rng = sampler_init(seed, (uint)p->pixel, (uint)p->sample);
    float3 o = p->origin.xyz, d = p->dir.xyz;

    Triangle tri = scene->tris[hit.tri];
    float3 ng = triangle_normal(&tri);
    float3 x = o + hit.t * d;
    float3 wo = -d;
    int segments = p->bounce + 1;                    /* path segments so far, camera one included */
    path_add_emission(scene, p, &tri, ng, wo, hit.t);
#if USE_MAX_DEPTH
    if (segments >= MAX_DEPTH) return false;
#endif
    if (p->bounce >= HARD_MAX_BOUNCES) return false;

    Material m = scene->materials[tri.material];
    float3 n = shading_normal(m.type, ng, wo);
    float3 ts, tt;
    make_basis(n, &ts, &tt);
    float3 wo_local = to_local(wo, ts, tt, n);
    bool nee_allowed = !is_specular(m.type);
#if USE_MAX_DEPTH
    nee_allowed = nee_allowed && segments + 1 <= MAX_DEPTH;
#endif
    if (nee_allowed) path_prepare_shadow_ray(scene, p, &rng, &m, x, ng, ts, tt, n, wo_local, shadow);
    return path_continue(scene, p, &rng, &m, x, ng, ts, tt, n, wo_local);
}

/* Extend the path by one vertex: trace, then shade (the shadow ray only prepared).
 * Returns false when the path has terminated. */
HELPER bool path_extend_deferred(const SceneView* scene, PathState* p, uint seed, LaneCounters* count,
                                 ShadowRay* shadow) {
    return path_shade_deferred(scene, p, path_trace(scene, p, count), seed, shadow);
}

/* Whether a shadow ray reaches its light. */
HELPER bool shadow_unoccluded(const SceneView* scene, const ShadowRay* r, LaneCounters* count) {
    count->shadow_rays += 1;
    return !trace_any(scene, r->origin, r->dir.xyz, 0.0f, r->length, &count->shadow_steps);
}

/* Extend by one vertex and trace the shadow ray at once (one path per work-item). */
HELPER bool path_extend(const SceneView* scene, PathState* p, uint seed, LaneCounters* count) {
    ShadowRay shadow;
    bool continues = path_extend_deferred(scene, p, seed, count, &shadow);
    if (shadow.slot >= 0 && shadow_unoccluded(scene, &shadow, count))
        p->radiance.xyz += shadow.contribution.xyz;
    return continues;
}

/* Write the sample's value to the pass output, where queued shadow rays may already have
 * added their part; .w becomes 0 (done) or 1 (not finite: the host counts and drops it). */
HELPER void path_finish(__global float4* out, const PathState* p) {
    float3 L = out[p->slot].xyz + p->radiance.xyz;
    out[p->slot] = all_finite(L) ? (float4)(L, 0.0f) : (float4)(0.0f, 0.0f, 0.0f, 1.0f);
}

#endif
