/* Bidirectional path tracing: stored vertices, the densities MIS needs, and the evaluation
 * of one connection strategy (s, t) = (s light vertices y_0..y_{s-1}, t eye vertices
 * z_0..z_{t-1}; z_0 is the camera, y_0 the point on the light).
 *
 * Conventions follow Veach's thesis (ch. 10) and pbrt-v3's bdpt.cpp (section 16.3):
 *   - every stored vertex keeps pdf_fwd, the area density with which its own subpath
 *     generated it, and pdf_rev, the area density of generating the *previous* vertex
 *     of its subpath from it in the reverse direction (so pdf_rev of vertex i is read from
 *     vertex i + 1);
 *   - at a connection the densities that change (the two endpoints and their predecessors)
 *     are recomputed, and the balance heuristic weight is 1 / (1 + sum of ratios r_i) over
 *     the other strategies that could have made the same path (pbrt-v3 eq. 16.4 ff.);
 *   - delta (specular) vertices cannot be connected, so their strategies are skipped; a
 *     specular bounce still enters the ratios of the others, with the density Veach uses
 *     (thesis sec. 10.3.5): the delta's coefficient 1 per projected solid angle, i.e.
 *     |cos| per solid angle (delta_pdf_dir). The geometry terms of a specular chain then
 *     cancel between strategies. pbrt-v3 puts 0 there (then 1 in the ratio): also unbiased,
 *     but it leaves a factor G(glass, floor) / G(light, glass) that hands caustics to the
 *     eye path instead of to light tracing, which samples them far better (measured: see tests/test_bdpt.py).
 * remap0 still turns a density of 0 into 1 in the ratios, as pbrt-v3 does.
 * A pinhole camera is a delta in position; its importance for the whole film is
 * We = 1 / (A cos^4 theta), A the image-plane area at distance 1 (pbrt-v3 sec. 16.1.1). */
#ifndef BDPT_H
#define BDPT_H

#include "common.h"
#include "bdpt_sampler.h"
#include "camera.h"
#include "bvh.h"
#include "lights.h"
#include "materials.h"

/* VERTEX_DELTA, VERTEX_CAMERA, VERTEX_LIGHT (y_0, the point sampled on a light): VertexFlag in
 * toolkit/core/layout.py; is_delta(), is_camera(), is_light_origin() and remap0(): bdpt_vertex.h. */
#include "bdpt_vertex.h"

/* MAX_VERTICES and vertex_index: where the random walk keeps its vertices. */
#include "vertex_memory.h"
#ifndef STRATEGY_IMAGES
#define STRATEGY_IMAGES 0  /* 1: connect kernels keep each strategy apart (render --strategies) */
#endif

/* ---- the pinhole camera as a vertex ----------------------------------------------------- */

HELPER float film_area(const Camera* cam) { return 4.0f * length(cam->right.xyz) * length(cam->up.xyz); }

/* Solid-angle density of the camera choosing direction w (uniform on the film). */
HELPER float camera_pdf_dir(const Camera* cam, float3 w) {
    float c = dot(w, cam->forward.xyz);
    return c > 0.0f ? 1.0f / (film_area(cam) * c * c * c) : 0.0f;
}

/* Pixel hit by direction w from the camera, or -1 outside the image. */
HELPER int camera_pixel(const Camera* cam, float3 w) {
    float c = dot(w, cam->forward.xyz);
    if (c <= 0.0f) return -1;
    float3 on_plane = w / c;
    float tx = length(cam->right.xyz), ty = length(cam->up.xyz);
    float sx = dot(on_plane, cam->right.xyz) / (tx * tx);
    float sy = dot(on_plane, cam->up.xyz) / (ty * ty);
    float x = 0.5f * (sx + 1.0f) * (float)cam->width;
    float y = 0.5f * (1.0f - sy) * (float)cam->height;
    if (!(x >= 0.0f && x < (float)cam->width && y >= 0.0f && y < (float)cam->height)) return -1;
    return min((int)y, cam->height - 1) * cam->width + min((int)x, cam->width - 1);
}

/* ---- densities ------------------------------------------------------------------------ */

/* Shading frame of a surface vertex seen from direction `toward` (two-sided materials flip). */
HELPER void vertex_frame(const SceneView* scene, const BdptVertex* v, float3 toward, float3* n, float3* ts, float3* tt) {
    *n = shading_normal(scene->materials[v->material].type, v->normal.xyz, toward);
    make_basis(*n, ts, tt);
}

/* f(wo, wi) at a surface vertex, directions in world space; wo towards where light goes. */
HELPER float3 vertex_bsdf(const SceneView* scene, const BdptVertex* v, float3 wo, float3 wi, float* pdf) {
    float3 n, ts, tt;
    vertex_frame(scene, v, wo, &n, &ts, &tt);
    Material m = scene->materials[v->material];
    return bsdf_eval(&m, to_local(wo, ts, tt, n), to_local(wi, ts, tt, n), pdf);
}

/* Convert a solid-angle density at `from` towards `to` into an area density at `to`. */
HELPER float to_area(float pdf_dir, float3 from, const BdptVertex* to) {
    float3 d = to->pos.xyz - from;
    float dist2 = dot(d, d);
    if (dist2 <= 0.0f) return 0.0f;
    if (is_camera(to)) return pdf_dir / dist2;      /* not on a surface: no cosine */
    return pdf_dir * fabs(dot(to->normal.xyz, d)) * rsqrt(dist2) / dist2;
}

/* The "density" of a specular bounce in direction w (cos_w = cos of w to the normal) for
 * MIS: the delta's coefficient 1 per projected solid angle, so |cos_w| per solid angle. */
HELPER float delta_pdf_dir(float cos_w) { return fabs(cos_w); }

/* Area density at `next` of sampling it from vertex v, which was reached from `prev`
 * (prev may be 0 for the camera and the light origin, which have no predecessor). */
HELPER float vertex_pdf(const SceneView* scene, const Camera* cam, const BdptVertex* prev, const BdptVertex* v,
                        const BdptVertex* next) {
    float3 w = normalize(next->pos.xyz - v->pos.xyz);
    float pdf_dir;
    if (is_delta(v)) {
        pdf_dir = delta_pdf_dir(dot(v->normal.xyz, w));
    } else if (is_camera(v)) {
        pdf_dir = camera_pdf_dir(cam, w);
    } else if (is_light_origin(v) && prev == 0) {
        pdf_dir = fmax(0.0f, dot(v->normal.xyz, w)) * INV_PI;   /* cosine-weighted emission */
    } else {
        float3 wo = normalize(prev->pos.xyz - v->pos.xyz);
        vertex_bsdf(scene, v, wo, w, &pdf_dir);
    }
    return to_area(pdf_dir, v->pos.xyz, next);
}

/* Area density of light sampling choosing the point of `v` (an eye vertex on a light), and
 * solid-angle density of the light emitting from there towards `to`, as an area density. */
HELPER float light_origin_pdf(const SceneView* scene, const BdptVertex* v) {
    return v->light >= 0 ? scene->tris[scene->lights[v->light].triangle].light_pdf : 0.0f;
}
HELPER float light_emit_pdf(const BdptVertex* v, const BdptVertex* to) {
    float3 w = normalize(to->pos.xyz - v->pos.xyz);
    return to_area(fmax(0.0f, dot(v->normal.xyz, w)) * INV_PI, v->pos.xyz, to);
}

/* ---- MIS: the weight of one strategy among all that could make this path (mis.h) ---- */

#include "mis.h"

/* ---- one connection ------------------------------------------------------------------- */

/* Firefly clamping (scene integrator.clamp, scenes/FORMAT.md): a connection's MIS-weighted
 * contribution whose largest RGB component m exceeds CLAMP is scaled by CLAMP / m (its colour
 * kept, as pbrt-v4's maxcomponentvalue). Per connection, not per sample: a sample's strategies
 * land in different pixels, and so both connect phases clamp the same values. Biased. */
HELPER float3 clamp_contribution(float3 value) {
#ifdef CLAMP
    float m = fmax(value.x, fmax(value.y, value.z));
    if (m > CLAMP) value *= CLAMP / m;
#endif
    return value;
}

typedef struct {
    float3 value;   /* contribution to the pixel (already MIS-weighted) */
    int pixel;      /* target pixel: the sample's own (t >= 2) or the splat's (t = 1); -1: none */
    float weight;   /* the MIS weight alone (for tests and per-strategy images) */
#if STRATEGY_IMAGES
    float3 unweighted;   /* the contribution before its MIS weight (render --strategies) */
#endif
} Connection;

HELPER bool visible(const SceneView* scene, const BdptVertex* a, const BdptVertex* b, int* steps) {
    float3 d = b->pos.xyz - a->pos.xyz;
    float3 from = is_camera(a) ? a->pos.xyz : offset_point(scene, a->pos.xyz, a->normal.xyz, d);
    float3 to = is_camera(b) ? b->pos.xyz : offset_point(scene, b->pos.xyz, b->normal.xyz, -d);
    float3 seg = to - from;
    float len = length(seg);
    if (!(len > 0.0f) || dot(seg, d) <= 0.0f) return false;
    return !trace_any(scene, from, seg / len, 0.0f, len, steps);
}

/* What the light subpath's end y_{s-1} sends towards w: the emitted radiance at the light
 * origin (one-sided), otherwise its BSDF for light arriving from y_{s-2}. */
HELPER float3 light_end_f(const SceneView* scene, const BdptVertex* qs, int s_len, float3 w) {
    if (s_len == 1)
        return dot(qs->normal.xyz, w) > 0.0f ? scene->lights[qs->light].emission.xyz : (float3)(0.0f);
    float unused;
    return vertex_bsdf(scene, qs, qs->wo.xyz, w, &unused);
}

/* Strategy (s, 1), light tracing: connect y_{s-1} to the camera; the result lands on another
 * pixel (*pixel). False when it cannot (delta vertex, outside the image, black, occluded). */
HELPER bool connect_to_camera(const SceneView* scene, const Camera* cam, __global const BdptVertex* eye,
                              __global const BdptVertex* light, int s_len, int* steps, float3* value,
                              int* pixel, ConnectionPdfs* c) {
    BdptVertex qs = light[s_len - 1], cam_v = eye[0];
    if (is_delta(&qs)) return false;
    float3 d = cam_v.pos.xyz - qs.pos.xyz;
    float dist2 = dot(d, d);
    float3 w = d * rsqrt(dist2);            /* from qs towards the camera */
    *pixel = camera_pixel(cam, -w);
    if (*pixel < 0) return false;
    float3 f = light_end_f(scene, &qs, s_len, w);
    if (is_black(f)) return false;
    float cos_cam = dot(-w, cam->forward.xyz);
    float we = 1.0f / (film_area(cam) * cos_cam * cos_cam * cos_cam * cos_cam);
    *value = qs.beta.xyz * f * fabs(dot(qs.normal.xyz, w)) * we * cos_cam / dist2;
    if (!visible(scene, &qs, &cam_v, steps)) return false;
    c->qs_rev = to_area(camera_pdf_dir(cam, -w), cam_v.pos.xyz, &qs);
    if (s_len > 1) {
        BdptVertex qsm = light[s_len - 2];
        c->qsm_rev = vertex_pdf(scene, cam, &cam_v, &qs, &qsm);
    }
    return true;
}

/* Evaluate strategy (s, t) of the sample whose subpaths are `eye` (t_max vertices) and `light`.
 * `own_pixel` is where eye-path strategies land. Returns value 0 / pixel -1 when the strategy
 * cannot make a path (delta endpoint, light's back side, occluded, outside the image...). */
HELPER Connection connect_strategy(const SceneView* scene, const Camera* cam, __global const BdptVertex* eye,
                                   __global const BdptVertex* light, int s_len, int t_len, int own_pixel,
                                   int* steps) {
    Connection out = {(float3)(0.0f), -1, 0.0f};
#if USE_MAX_DEPTH
    if (s_len + t_len - 1 > MAX_DEPTH) return out;
#endif
    ConnectionPdfs c = {0.0f, 0.0f, 0.0f, 0.0f};
    float3 value;
    int pixel = own_pixel;
    if (s_len == 0) {
        /* The eye subpath found a light by itself. */
        BdptVertex pt = eye[t_len - 1], ptm = eye[t_len - 2];
        if (pt.light < 0 || dot(pt.normal.xyz, pt.wo.xyz) <= 0.0f) return out;
        value = pt.beta.xyz * scene->lights[pt.light].emission.xyz;
        c.pt_rev = light_origin_pdf(scene, &pt);
        c.ptm_rev = light_emit_pdf(&pt, &ptm);
    } else if (t_len == 1) {
        if (!connect_to_camera(scene, cam, eye, light, s_len, steps, &value, &pixel, &c)) return out;
    } else {
        /* Connect y_{s-1} and z_{t-1} with a shadow ray. */
        BdptVertex qs = light[s_len - 1], pt = eye[t_len - 1];
        if (is_delta(&qs) || is_delta(&pt)) return out;
        float3 d = pt.pos.xyz - qs.pos.xyz;
        float dist2 = dot(d, d);
        float3 w = d * rsqrt(dist2);            /* from qs towards pt */
        float3 fq = light_end_f(scene, &qs, s_len, w);
        float unused;
        float3 fp = vertex_bsdf(scene, &pt, pt.wo.xyz, -w, &unused);
        if (is_black(fq) || is_black(fp)) return out;
        float g = fabs(dot(qs.normal.xyz, w)) * fabs(dot(pt.normal.xyz, w)) / dist2;
        value = qs.beta.xyz * fq * g * fp * pt.beta.xyz;
        if (!visible(scene, &qs, &pt, steps)) return out;
        BdptVertex ptm = eye[t_len - 2];
        BdptVertex qsm = light[max(s_len - 2, 0)];
        c.pt_rev = vertex_pdf(scene, cam, s_len > 1 ? &qsm : 0, &qs, &pt);
        c.ptm_rev = vertex_pdf(scene, cam, &qs, &pt, &ptm);
        c.qs_rev = vertex_pdf(scene, cam, &ptm, &pt, &qs);
        if (s_len > 1) c.qsm_rev = vertex_pdf(scene, cam, &pt, &qs, &qsm);
    }
    out.weight = mis_weight(eye, light, s_len, t_len, &c);
    out.value = clamp_contribution(value * out.weight);
    out.pixel = pixel;
#if STRATEGY_IMAGES
    out.unweighted = value;
#endif
    return out;
}

/* What a connect kernel stores of a connection, (value, MIS weight). Built for per-strategy
 * images (STRATEGY_IMAGES, toolkit/measure/strategies.py), the value is the unweighted one: the host
 * weighs it (float32 value * weight, as above) for the image and keeps both for the strategies. */
HELPER float4 connection_record(const Connection* c) {
#if STRATEGY_IMAGES
    return (float4)(c->unweighted, c->weight);
#else
    return (float4)(c->value, c->weight);
#endif
}

/* Which strategies a sample has and how they are numbered (connection_count, connection_strategy),
 * and the per-strategy images' numbering (strategy_index, strategy_count): toolkit/core/bdpt_indices.py,
 * generated into layout.h. */
#endif
