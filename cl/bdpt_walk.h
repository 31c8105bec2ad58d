/* The random-walk phase shared by both BDPT techniques (the talk's "Random Walk Phase"):
 * an eye-path stream and a light-path stream, each extended by one vertex per step and
 * compacted at once (cl/compact.h); vertices go to pre-allocated per-sample memory.
 * A sample terminates when both of its subpaths have; regeneration is postponed until a
 * fraction of the samples has terminated (host: toolkit/techniques/bdpt_evaluator.py). */
#ifndef BDPT_WALK_H
#define BDPT_WALK_H

#include "bdpt.h"
#include "compact.h"
#include "bdpt_regeneration.h"

/* Store one vertex per work-item at memory[index] (index < 0: nothing to store).
 * Direct: each work-item writes its own vertex (96 bytes), far from its neighbours' (uncoalesced).
 * Coalesced (the talk's "Coalesced Vertex Scatter", like a matrix transpose): the group
 * stages its vertices in local memory, then work-item j writes word j, j + LOCAL_SIZE, ...
 * of the staged block, so consecutive work-items write consecutive words of one vertex.
 * Both leave identical memory. Every work-item of the group must call this (barriers). */
HELPER void store_vertex(__global BdptVertex* memory, int index, const BdptVertex* v,
                         __local uint* stage, __local int* dest) {
#if COALESCED_SCATTER
    int lid = get_local_id(0);
    dest[lid] = index;
    if (index >= 0) {
        const uint* words = (const uint*)v;
        for (int w = 0; w < VERTEX_WORDS; ++w) stage[lid * VERTEX_WORDS + w] = words[w];
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    __global uint* out = (__global uint*)memory;
    for (int k = lid; k < LOCAL_SIZE * VERTEX_WORDS; k += LOCAL_SIZE) {
        int target = dest[k / VERTEX_WORDS];
        if (target >= 0) out[vertex_word(target, k % VERTEX_WORDS)] = stage[k];
    }
    barrier(CLK_LOCAL_MEM_FENCE);
#else
    if (index >= 0) memory[index] = *v;
#endif
}

/* The sampler of sample `id` of the pass (cl/bdpt_sampler.h; the dimension table:
 * toolkit/core/sample_dims.py). Under MLT the sample is chain `id`'s proposal and
 * pass.sample_base the iteration (toolkit/techniques/mlt.py). */
#if MLT
HELPER BdptSampler bdpt_sampler_mlt(const BdptPass* pass, int id, __global const float* primary) {
    BdptSampler sampler = {mlt_mutation_sampler(pass->seed, id, pass->sample_base), primary,
                           (uint)pass->chains, (uint)id};
    return sampler;
}
#define bdpt_sampler(cam, pass, id) bdpt_sampler_mlt(pass, id, mlt_primary)
#else
HELPER BdptSampler bdpt_sampler(const Camera* cam, const BdptPass* pass, int id) {
    return sampler_init(pass->seed, (uint)sample_pixel(cam, id), (uint)sample_number(cam, id, pass->sample_base));
}
#endif

/* The pixel of sample `id` and the camera sample (*u, *v) inside it. BDPT: the pass assigns
 * the pixel (camera.h). MLT: the pixel is part of the primary sample, (*u, *v) in [0, 1)^2
 * cover the whole image and are turned into a pixel and a position inside it. */
HELPER int bdpt_pixel(const Camera* cam, int id, float* u, float* v) {
#if MLT
    float x = *u * (float)cam->width, y = *v * (float)cam->height;
    int px = min((int)x, cam->width - 1), py = min((int)y, cam->height - 1);
    *u = fmin(x - (float)px, 0.99999994f);
    *v = fmin(y - (float)py, 0.99999994f);
    return py * cam->width + px;
#else
    return sample_pixel(cam, id);
#endif
}

/* Russian roulette (common.h) at vertex k, as in the path tracers, but from BDPT_RR_DEPTH, half
 * the scene's depth rounded up (host: bdpt_evaluator.py): two subpaths of that depth and their
 * connection already make a path longer than the path tracer's roulette-free part, and every
 * vertex more costs connections to all vertices of the other subpath. Light paths compare with
 * their throughput at y_1 (SUBPATH_RR_NORMALISER, layout.h). False when the subpath stops. */
HELPER bool subpath_roulette(Subpath* p, BdptSampler* rng, int k, bool light_path) {
#if USE_RUSSIAN_ROULETTE
    if (k >= BDPT_RR_DEPTH) {
        float3 beta = p->beta.xyz;
        float u = bdpt_sample(rng, bdpt_scatter_dim(k, light_path, BDPT_SCATTER_ROULETTE));
        if (!roulette(&beta, SUBPATH_RR_NORMALISER(p), u)) return false;
        p->beta.xyz = beta;
    }
#endif
    return true;
}

/* Extend a subpath by one vertex: intersect, store the vertex, sample the BSDF, roulette.
 * Sets *store_at to where the new vertex goes. Returns false when the subpath has ended. */
HELPER bool subpath_extend(const SceneView* scene, Subpath* p, BdptSampler* rng, bool light_path,
                           BdptVertex* v, int* store_at, int* steps) {
    float3 d = p->dir.xyz;
    Hit h = trace_closest(scene, p->origin.xyz, d, 0.0f, INFINITY, steps);
    if (h.tri < 0) return false;
    Triangle tri = scene->tris[h.tri];
    float3 ng = triangle_normal(&tri);
    float3 x = p->origin.xyz + h.t * d;
    float3 from_prev = x - p->prev_pos.xyz;
    float dist2 = dot(from_prev, from_prev);
    int k = p->vertices;
    Material m = scene->materials[tri.material];
    BdptVertex stored = {
        .pos = (float4)(x, 0.0f), .normal = (float4)(ng, 0.0f), .wo = (float4)(-d, 0.0f),
        .beta = (float4)(p->beta.xyz, 0.0f), .material = tri.material,
        .flags = is_specular(m.type) ? VERTEX_DELTA : 0, .light = tri.light,
        /* the density of the direction (see delta_pdf_dir after a specular bounce), as an area density here */
        .pdf_fwd = SUBPATH_PDF_DIR(p) * fabs(dot(ng, d)) / dist2,
        .pdf_rev = 0.0f};   /* set below once the next direction is known */
    *v = stored;
    *store_at = vertex_index(p->slot, k);
    p->vertices = k + 1;

    bool can_continue = k + 1 < MAX_VERTICES;
#if USE_MAX_DEPTH
    can_continue = can_continue && k < MAX_DEPTH;
#endif
    if (!can_continue) return false;

    float3 n = shading_normal(m.type, ng, -d);
    float3 ts, tt;
    make_basis(n, &ts, &tt);
    float3 wo_local = to_local(-d, ts, tt, n);
    BsdfSample bs;
    if (!bsdf_sample(&m, wo_local, bdpt_sample(rng, bdpt_scatter_dim(k, light_path, BDPT_SCATTER_BSDF_U)),
                     bdpt_sample(rng, bdpt_scatter_dim(k, light_path, BDPT_SCATTER_BSDF_V)),
                     bdpt_sample(rng, bdpt_scatter_dim(k, light_path, BDPT_SCATTER_BSDF_LOBE)), &bs))
        return false;
    float3 wi = to_world(bs.wi, ts, tt, n);
    /* Reverse density: of this vertex choosing the previous one, had it arrived along wi. */
    float pdf_rev_dir = delta_pdf_dir(wo_local.z);
    if (!bs.specular) bsdf_eval(&m, bs.wi, wo_local, &pdf_rev_dir);
    if (!(p->prev_flags & VERTEX_CAMERA))
        v->pdf_rev = pdf_rev_dir * fabs(dot(p->prev_normal.xyz, from_prev)) * rsqrt(dist2) / dist2;

    p->beta.xyz *= bs.weight;
    p->origin.xyz = offset_point(scene, x, ng, wi);
    SUBPATH_PDF_DIR(p) = bs.specular ? delta_pdf_dir(bs.wi.z) : bs.pdf;
    p->dir = (float4)(wi, 0.0f);
    p->prev_pos = (float4)(x, 0.0f);
    p->prev_normal = (float4)(ng, 0.0f);
    p->prev_flags = v->flags;
    return subpath_roulette(p, rng, k, light_path) && !is_black(p->beta.xyz);
}

/* The walk's counters, one int buffer on the device (WalkCounter in toolkit/core/layout.py):
 * counters[EYE_LENGTH], [LIGHT_LENGTH] the streams' lengths, which each step reads;
 * counters[EYE_SURVIVORS], [LIGHT_SURVIVORS], [TERMINATED_SAMPLES] what it counts. The host copies
 * the survivors onto the lengths on the device after a step, and reads the buffer behind the walk,
 * so it never waits for a count before the next launch.
 * A slot's `live` counts its subpaths still walking (SlotState in toolkit/core/layout.py):
 * SLOT_BOTH_WALKING after regeneration, SLOT_ONE_WALKING, SLOT_TERMINATED when both have
 * ended (it waits for its connections), SLOT_CONNECTING once listed for a connect phase,
 * SLOT_IDLE when the pass's budget left it empty. */

/* One random-walk step over a compacted subpath stream (eye or light) of counters[EYE_ or
 * LIGHT_LENGTH] subpaths; the launch may cover more (a bound the host knows), and a work-group
 * wholly past the length leaves at once. Survivors are packed
 * into `next_stream` and counted in counters[EYE_ or LIGHT_SURVIVORS]; a subpath that ends records
 * its vertex count, and the sample whose second subpath this was counts as terminated.
 * `stream` and `next_stream` are Subpath structures of arrays of pass_args.capacity records (layout.h). */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void bdpt_extend(SCENE_PARAMS, const Camera cam, const BdptPass pass_args, const BdptStep walk_step,
                 __global void* stream, __global void* next_stream, volatile __global int* counters,
                 __global BdptVertex* vertices, volatile __global BdptSlot* slots, __global LaneCounts* lane_counts
                 BDPT_SAMPLER_PARAM)
{
    int gid = get_global_id(0);
    const int light_path = walk_step.light_path, length = counters[light_path ? LIGHT_LENGTH : EYE_LENGTH];
    /* All the group's work-items leave together, so none waits at a barrier the others skip. */
    if (get_group_id(0) * get_local_size(0) >= length) return;
    __local int scratch[COMPACT_SCRATCH_INTS];
    __local uint stage[LOCAL_SIZE * VERTEX_WORDS];
    __local int dest[LOCAL_SIZE];
    bool alive = false;
    int store_at = -1, steps = 0;
    BdptVertex v;
    Subpath p;
    /* No early return: every work-item must reach the barriers of the scatter and compaction. */
    if (gid < length) {
        SceneView scene = SCENE_INIT;
        p = subpath_load(subpath_soa(stream, pass_args.capacity), gid);
        BdptSampler rng = bdpt_sampler(&cam, &pass_args, slots[p.slot].sample_id);
        alive = subpath_extend(&scene, &p, &rng, light_path != 0, &v, &store_at, &steps);
        if (!alive) {
            if (light_path) slots[p.slot].light_vertices = p.vertices;
            else slots[p.slot].eye_vertices = p.vertices;
            if (atomic_dec(&slots[p.slot].live) == SLOT_ONE_WALKING) atomic_inc(&counters[TERMINATED_SAMPLES]);
        }
    }
    store_vertex(vertices, store_at, &v, stage, dest);
    int slot = immediate_compact_slot(alive, scratch, &counters[light_path ? LIGHT_SURVIVORS : EYE_SURVIVORS]);
    if (slot >= 0) subpath_store(subpath_soa(next_stream, pass_args.capacity), slot, &p);
#if COUNT_SIMD
    if (gid < length) {
        LaneCounts lane = {.work = 1, .closest_steps = steps};
        lane_counts[gid] = lane;
    }
#endif
}

/* Start new samples in the pool slots listed in `slot_list` (those bdpt_mark_terminated
 * listed): the first r.fresh get samples r.first_id, r.first_id + 1, ... (consecutive pixels);
 * the rest go idle (budget spent). Writes z_0 (camera) and y_0 (point on a light) and appends
 * both subpaths to their streams, after the subpaths there: slot_list[pass_args.pool] and
 * [pass_args.pool + 1] hold the streams' lengths (copied from the walk's counters on the device,
 * so the host needs not know them; bdpt_regenerated then adds the new subpaths to them). */
__kernel void bdpt_regenerate(SCENE_PARAMS, const Camera cam, const BdptPass pass_args, const BdptRegeneration r,
                              __global const int* slot_list, __global void* eye_stream, __global void* light_stream,
                              __global BdptVertex* eye_vertices, __global BdptVertex* light_vertices,
                              __global BdptSlot* slots BDPT_SAMPLER_PARAM)
{
    int gid = get_global_id(0);
    if (gid >= r.count) return;
    const int eye_base = slot_list[pass_args.pool], light_base = slot_list[pass_args.pool + 1];
    int slot = slot_list[gid];
    int id = bdpt_regeneration_sample(&r, gid);
    if (id < 0) { slots[slot].live = SLOT_IDLE; return; }
    SceneView scene = SCENE_INIT;
    BdptSampler rng = bdpt_sampler(&cam, &pass_args, id);
    float3 eye_pos = cam.origin.xyz, forward = cam.forward.xyz;

    /* Eye subpath: z_0 is the pinhole; the first direction is the camera sample (camera.h). */
    float u = bdpt_sample(&rng, BDPT_DIM_PIXEL), v = bdpt_sample(&rng, BDPT_DIM_PIXEL + 1);
    int pixel = bdpt_pixel(&cam, id, &u, &v);
    float3 w = camera_sample(&cam, pixel, u, v);
    BdptVertex z0 = {.pos = (float4)(eye_pos, 0.0f), .normal = (float4)(forward, 0.0f), .wo = (float4)(0.0f),
                     .beta = (float4)(1.0f, 1.0f, 1.0f, 0.0f), .material = -1, .flags = VERTEX_CAMERA,
                     .light = -1, .pdf_fwd = 1.0f, .pdf_rev = 0.0f};
    eye_vertices[vertex_index(slot, 0)] = z0;
    /* .w lanes (layout.h): SUBPATH_PDF_DIR the camera's density of w, SUBPATH_RR_NORMALISER 1 */
    Subpath e = {.origin = (float4)(eye_pos, camera_pdf_dir(&cam, w)), .dir = (float4)(w, 0.0f),
                 .beta = (float4)(1.0f), .prev_pos = (float4)(eye_pos, 0.0f), .prev_normal = (float4)(forward, 0.0f),
                 .slot = slot, .vertices = 1, .prev_flags = VERTEX_CAMERA};
    subpath_store(subpath_soa(eye_stream, pass_args.capacity), eye_base + gid, &e);

    /* Light subpath: y_0 on a light (chosen by power), then a cosine-weighted direction. */
    LightSample ls = sample_light(&scene, bdpt_sample(&rng, BDPT_DIM_LIGHT_PICK),
                                  bdpt_sample(&rng, BDPT_DIM_LIGHT_POINT), bdpt_sample(&rng, BDPT_DIM_LIGHT_POINT + 1));
    float inv_pdf = 1.0f / ls.pdf_area;
    BdptVertex y0 = {.pos = (float4)(ls.p, 0.0f), .normal = (float4)(ls.n, 0.0f), .wo = (float4)(0.0f),
                     .beta = (float4)(inv_pdf, inv_pdf, inv_pdf, 0.0f),
                     .material = scene.tris[scene.lights[ls.light].triangle].material, .flags = VERTEX_LIGHT,
                     .light = ls.light, .pdf_fwd = ls.pdf_area, .pdf_rev = 0.0f};
    light_vertices[vertex_index(slot, 0)] = y0;
    float3 ts, tt;
    make_basis(ls.n, &ts, &tt);
    float3 emit_local = sample_cosine_hemisphere(bdpt_sample(&rng, BDPT_DIM_EMIT_DIR), bdpt_sample(&rng, BDPT_DIM_EMIT_DIR + 1));
    float3 dir = to_world(emit_local, ts, tt, ls.n);
    /* Le cos / (pdf_area * cos / pi) = Le pi / pdf_area */
    float3 beta = ls.emission * (PI * inv_pdf);
    /* .w lanes: SUBPATH_PDF_DIR the cosine-weighted emission's density, SUBPATH_RR_NORMALISER max(beta) */
    Subpath l = {.origin = (float4)(offset_point(&scene, ls.p, ls.n, dir), emit_local.z * INV_PI),
                 .dir = (float4)(dir, 0.0f), .beta = (float4)(beta, max3(beta)), .prev_pos = (float4)(ls.p, 0.0f),
                 .prev_normal = (float4)(ls.n, 0.0f), .slot = slot, .vertices = 1, .prev_flags = VERTEX_LIGHT};
    subpath_store(subpath_soa(light_stream, pass_args.capacity), light_base + gid, &l);

    BdptSlot started = {.live = SLOT_BOTH_WALKING, .sample_id = id, .eye_vertices = 1, .light_vertices = 1,
                        .pixel = pixel};
    slots[slot] = started;
}

/* After bdpt_regenerate (one work-item): the `fresh` new subpaths join the streams' lengths, and
 * the `count` regenerated slots no longer count as terminated (samples that terminated since
 * bdpt_mark_terminated listed them still do: they wait for the next connect phase). */
__kernel void bdpt_regenerated(volatile __global int* counters, const int fresh, const int count)
{
    if (get_global_id(0) != 0) return;
    counters[EYE_LENGTH] += fresh;
    counters[LIGHT_LENGTH] += fresh;
    counters[TERMINATED_SAMPLES] -= count;
}

/* If at least `threshold` samples have terminated (counters[TERMINATED_SAMPLES]: the device
 * decides, the host reads no count first), flags[i] = 1 for the pool slots whose sample has
 * terminated and waits for its connections, else 0 everywhere. The flagged slots become
 * SLOT_CONNECTING, so the slots that terminate while the host queues further walk steps before
 * their connect phase (bdpt_evaluator.py) wait for the next one. */
__kernel void bdpt_mark_terminated(const int pool, const int threshold, __global const int* counters,
                                   __global BdptSlot* slots, __global int* flags)
{
    int gid = get_global_id(0);
    if (gid >= pool) return;
    int terminated = counters[TERMINATED_SAMPLES] >= threshold && slots[gid].live == SLOT_TERMINATED;
    if (terminated) slots[gid].live = SLOT_CONNECTING;
    flags[gid] = terminated;
}

#endif
