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
#include "simd_counters.h"

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
 * pass.sample_base the iteration (toolkit/techniques/mlt.py). A batch of more samples than
 * chains (start = pool's candidates, large steps all) counts on by iteration: sample
 * k * chains + c is chain c's proposal of iteration sample_base + k. */
#if MLT
HELPER BdptSampler bdpt_sampler_mlt(const BdptPass* pass, int id, __global const float* primary) {
    int chain = id % pass->chains;
    BdptSampler sampler = {mlt_mutation_sampler(pass->seed, chain, pass->sample_base + id / pass->chains), primary,
                           (uint)pass->chains, (uint)chain};
    return sampler;
}
#define bdpt_sampler(pass, id) bdpt_sampler_mlt(pass, id, mlt_primary)
#else
/* BDPT: sample `id`'s pixel and number as the path tracers' (camera.h), from the pass's copy of
 * the camera's pixel count. */
HELPER BdptSampler bdpt_sampler(const BdptPass* pass, int id) {
    return sampler_init(pass->seed, (uint)pixel_of_sample(pass->pixels, id),
                        (uint)number_of_sample(pass->pixels, id, pass->sample_base));
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

/* The walk's counters, one int buffer on the device (WalkCounter in toolkit/core/layout.py): the
 * streams' lengths in a ring of three (eye, light) pairs, so that no step waits for the host to
 * clear or copy a count: walk step k reads its lengths from pair k % 3, counts its survivors into
 * pair (k + 1) % 3, which the step before cleared, and clears pair (k + 2) % 3 for the step after.
 * counters[TERMINATED_SAMPLES] counts the samples that terminated and wait to be listed;
 * counters[STEP_EYE_LENGTH], [STEP_LIGHT_LENGTH] the lengths the last step extended (the SIMD
 * counters read them); counters[WALK_STEPS] the steps that found subpaths to extend (how long
 * the pass's walk took, which tells the host when to list the next pass's last samples). The
 * host reads the buffer behind the walk, so it never waits for a count before the next launch.
 * A slot's `live` counts its subpaths still walking (SlotState in toolkit/core/layout.py):
 * SLOT_BOTH_WALKING after regeneration, SLOT_ONE_WALKING, SLOT_TERMINATED when both have
 * ended (it waits for its connections), SLOT_CONNECTING once listed for a connect phase,
 * SLOT_IDLE when the pass's budget left it empty. */
#define RING_LENGTHS(ring) (LENGTH_RING + 2 * ((ring) % 3))   /* the eye length of a pair; the light length follows */

/* One random-walk step of one stream (walk_step.light: 0 the eye stream, 1 the light stream;
 * the host launches it once per stream). The stream is a compacted subpath stream of the ring's
 * length plus walk_step.appended (the subpaths regenerated since that count); the launch may
 * cover more (a bound the host knows), and a work-group wholly past the length leaves at once.
 * Survivors are packed into the stream's next buffer and counted in the ring's next pair; a
 * subpath that ends records its vertex count, and the sample whose second subpath this was
 * counts as terminated. The streams are Subpath structures of arrays of pass_args.capacity
 * records (layout.h). */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void bdpt_extend(SCENE_PARAMS, const BdptPass pass_args, const BdptStep walk_step,
                 __global void* stream, __global void* next_stream, volatile __global int* counters,
                 __global BdptVertex* vertices, volatile __global BdptSlot* slots, __global LaneCounts* lane_counts,
                 volatile __global uint* simd_log BDPT_SAMPLER_PARAM)
{
    const bool light_path = walk_step.light != 0;
    const int length = counters[RING_LENGTHS(walk_step.ring) + walk_step.light] + walk_step.appended;
    if (get_global_id(0) == 0) {     /* no other work-item reads these during the step */
        counters[RING_LENGTHS(walk_step.ring + 2) + walk_step.light] = 0;
        counters[STEP_EYE_LENGTH + walk_step.light] = length;   /* STEP_LIGHT_LENGTH follows it */
        /* the eye launch counts the step if either stream has subpaths (the light's length is final) */
        if (!light_path && length + counters[RING_LENGTHS(walk_step.ring) + 1] + walk_step.appended > 0)
            counters[WALK_STEPS] += 1;
#if COUNT_SIMD
        if (walk_step.simd_row >= 0) simd_log[(walk_step.simd_row * SIMD_FIELDS + SIMD_LANES) * 2] = (uint)max(length, 0);
#endif
    }
    const int first = (int)get_group_id(0) * LOCAL_SIZE;
    /* All the group's work-items leave together, so none waits at a barrier the others skip. */
    if (first >= length) return;
    __local int scratch[COMPACT_SCRATCH_INTS];
    __local uint stage[LOCAL_SIZE * VERTEX_WORDS];
    __local int dest[LOCAL_SIZE];
#if COUNT_SIMD
    __local uint simd_lanes[2 * LOCAL_SIZE];   /* simd_count_group's */
#endif
    const int index = first + get_local_id(0);
    bool alive = false;
    int store_at = -1, steps = 0;
    BdptVertex v;
    Subpath p;
    /* No early return: every work-item must reach the barriers of the scatter and compaction. */
    if (index < length) {
        SceneView scene = SCENE_INIT;
        p = subpath_load(subpath_soa(stream, pass_args.capacity), index);
        BdptSampler rng = bdpt_sampler(&pass_args, slots[p.slot].sample_id);
        alive = subpath_extend(&scene, &p, &rng, light_path, &v, &store_at, &steps);
        if (!alive) {
            if (light_path) slots[p.slot].light_vertices = p.vertices;
            else slots[p.slot].eye_vertices = p.vertices;
            if (atomic_dec(&slots[p.slot].live) == SLOT_ONE_WALKING) atomic_inc(&counters[TERMINATED_SAMPLES]);
        }
    }
    store_vertex(vertices, store_at, &v, stage, dest);
    const int survivors = RING_LENGTHS(walk_step.ring + 1) + walk_step.light;
    int slot = immediate_compact_slot(alive, scratch, &counters[survivors]);
    if (slot >= 0) subpath_store(subpath_soa(next_stream, pass_args.capacity), slot, &p);
#if COUNT_SIMD
    if (index < length) {
        LaneCounts lane = {.work = 1, .closest_steps = steps};
        lane_counts[index] = lane;
    }
    /* The step's sums into the step log here, not by a counting launch after it (simd_row < 0: the
     * host counts this step's lanes itself, or with that launch). */
    simd_count_group(index < length, (uint)steps, index < length ? p.slot : 0, simd_log, walk_step.simd_row,
                     (volatile __global int*)(simd_log + walk_step.simd_stamps_at), walk_step.simd_stamp,
                     walk_step.simd_warp_width, simd_lanes);
#endif
}

/* The light subpath of a new sample: y_0 on a light (chosen by power), then a cosine-weighted
 * direction; stored at entry `at` of the light stream and vertex 0 of the slot's light vertices. */
HELPER void bdpt_start_light_subpath(SceneView* scene, BdptSampler* rng, int slot, int at, int capacity,
                                     __global void* stream, __global BdptVertex* vertices)
{
    LightSample ls = sample_light(scene, bdpt_sample(rng, BDPT_DIM_LIGHT_PICK),
                                  bdpt_sample(rng, BDPT_DIM_LIGHT_POINT), bdpt_sample(rng, BDPT_DIM_LIGHT_POINT + 1));
    float inv_pdf = 1.0f / ls.pdf_area;
    BdptVertex y0 = {.pos = (float4)(ls.p, 0.0f), .normal = (float4)(ls.n, 0.0f), .wo = (float4)(0.0f),
                     .beta = (float4)(inv_pdf, inv_pdf, inv_pdf, 0.0f),
                     .material = scene->tris[scene->lights[ls.light].triangle].material, .flags = VERTEX_LIGHT,
                     .light = ls.light, .pdf_fwd = ls.pdf_area, .pdf_rev = 0.0f};
    vertices[vertex_index(slot, 0)] = y0;
    float3 ts, tt;
    make_basis(ls.n, &ts, &tt);
    float3 emit_local = sample_cosine_hemisphere(bdpt_sample(rng, BDPT_DIM_EMIT_DIR), bdpt_sample(rng, BDPT_DIM_EMIT_DIR + 1));
    float3 dir = to_world(emit_local, ts, tt, ls.n);
    /* Le cos / (pdf_area * cos / pi) = Le pi / pdf_area */
    float3 beta = ls.emission * (PI * inv_pdf);
    /* .w lanes: SUBPATH_PDF_DIR the cosine-weighted emission's density, SUBPATH_RR_NORMALISER max(beta) */
    Subpath l = {.origin = (float4)(offset_point(scene, ls.p, ls.n, dir), emit_local.z * INV_PI),
                 .dir = (float4)(dir, 0.0f), .beta = (float4)(beta, max3(beta)), .prev_pos = (float4)(ls.p, 0.0f),
                 .prev_normal = (float4)(ls.n, 0.0f), .slot = slot, .vertices = 1, .prev_flags = VERTEX_LIGHT};
    subpath_store(subpath_soa(stream, capacity), at, &l);
}

/* Start new samples in the pool slots listed in `slot_list` (those bdpt_list_terminated listed):
 * the first r.fresh get samples r.first_id, r.first_id + 1, ... (consecutive pixels); the rest
 * go idle (budget spent). Launched once per stream (r.light): the eye launch writes z_0 (camera),
 * the eye subpath and the slot, the light launch y_0 (a point on a light) and the light subpath;
 * each appends its subpaths to its stream, after the subpaths there: the length in the counters'
 * ring (pair r.ring) plus the r.appended subpaths appended since. The next walk step adds the new
 * ones to those lengths (BdptStep.appended), so the host needs not know them. The sampler gives
 * each dimension by its number, so the two launches draw what one did. */
__kernel void bdpt_regenerate(SCENE_PARAMS, const Camera cam, const BdptPass pass_args, const BdptRegeneration r,
                              __global const int* slot_list, __global const int* counters, __global void* stream,
                              __global BdptVertex* vertices, __global BdptSlot* slots BDPT_SAMPLER_PARAM)
{
    int gid = get_global_id(0);
    if (gid >= r.count) return;
    const int base = counters[RING_LENGTHS(r.ring) + r.light] + r.appended;
    int slot = slot_list[gid];
    int id = bdpt_regeneration_sample(&r, gid);
    if (id < 0) {
        if (!r.light) slots[slot].live = SLOT_IDLE;
        return;
    }
    SceneView scene = SCENE_INIT;
    BdptSampler rng = bdpt_sampler(&pass_args, id);
    if (r.light) {
        bdpt_start_light_subpath(&scene, &rng, slot, base + gid, pass_args.capacity, stream, vertices);
        return;
    }
    float3 eye_pos = cam.origin.xyz, forward = cam.forward.xyz;

    /* Eye subpath: z_0 is the pinhole; the first direction is the camera sample (camera.h). */
    float u = bdpt_sample(&rng, BDPT_DIM_PIXEL), v = bdpt_sample(&rng, BDPT_DIM_PIXEL + 1);
    int pixel = bdpt_pixel(&cam, id, &u, &v);
    float3 w = camera_sample(&cam, pixel, u, v);
    BdptVertex z0 = {.pos = (float4)(eye_pos, 0.0f), .normal = (float4)(forward, 0.0f), .wo = (float4)(0.0f),
                     .beta = (float4)(1.0f, 1.0f, 1.0f, 0.0f), .material = -1, .flags = VERTEX_CAMERA,
                     .light = -1, .pdf_fwd = 1.0f, .pdf_rev = 0.0f};
    vertices[vertex_index(slot, 0)] = z0;
    /* .w lanes (layout.h): SUBPATH_PDF_DIR the camera's density of w, SUBPATH_RR_NORMALISER 1 */
    Subpath e = {.origin = (float4)(eye_pos, camera_pdf_dir(&cam, w)), .dir = (float4)(w, 0.0f),
                 .beta = (float4)(1.0f), .prev_pos = (float4)(eye_pos, 0.0f), .prev_normal = (float4)(forward, 0.0f),
                 .slot = slot, .vertices = 1, .prev_flags = VERTEX_CAMERA};
    subpath_store(subpath_soa(stream, pass_args.capacity), base + gid, &e);

    BdptSlot started = {.live = SLOT_BOTH_WALKING, .sample_id = id, .eye_vertices = 1, .light_vertices = 1,
                        .pixel = pixel};
    slots[slot] = started;
}

/* Listing the terminated samples for a connect phase, on the device, in three launches after the
 * connect phase's count kernel has written each slot's records (counts[slot]):
 *   bdpt_mark_terminated  if enough samples have terminated, marks them (SLOT_CONNECTING), and sums
 *                         each work-group's records and listed slots;
 *   bdpt_list_offsets     one work-group: where each work-group's records and listed slots start,
 *                         and the listing's totals for the host (one small read, looked at later);
 *   bdpt_list_terminated  each slot's first record (firsts: the exclusive scan of the counts of the
 *                         listed slots, in slot order, as the connect phases need it) and the list of
 *                         the listed slots, in slot order (regeneration restarts them).
 * Three launches where a multi-level scan and a compaction took seven or more, and the host
 * clears and copies nothing. */

/* If at least `threshold` samples have terminated (counters[TERMINATED_SAMPLES]: the device
 * decides, the host reads no count first), the slots whose sample has terminated become
 * SLOT_CONNECTING, so that the slots that terminate while the host queues further walk steps
 * before their connect phase (bdpt_evaluator.py) wait for the next one. block_sums[group]: the
 * group's records (.x) and listed slots (.y). */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void bdpt_mark_terminated(const int pool, const int threshold, __global const int* counters,
                          __global BdptSlot* slots, __global const int* counts, __global int2* block_sums)
{
    __local int scratch[COMPACT_SCRATCH_INTS];
    int gid = get_global_id(0);
    bool listed = gid < pool && counters[TERMINATED_SAMPLES] >= threshold && slots[gid].live == SLOT_TERMINATED;
    if (listed) slots[gid].live = SLOT_CONNECTING;
    int records, listed_slots;
    compact_group_scan(listed ? counts[gid] : 0, scratch, &records);
    compact_group_scan(listed ? 1 : 0, scratch, &listed_slots);
    if (get_local_id(0) == 0) block_sums[get_group_id(0)] = (int2)(records, listed_slots);
}

/* One work-group: block_sums (the `blocks` groups' records and listed slots) become their
 * exclusive scan, where each group's records and listed slots start. Each work-item adds a run
 * of consecutive groups, one scan over the work-group gives the runs' starts, and each work-item
 * walks its run again. listing (ListingInt in toolkit/core/layout.py): the slots listed and their
 * records, the streams' lengths now (pair `ring` of the counters), which bound the host's later
 * launches, and the walk's steps so far. The listed samples no longer count as terminated. */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void bdpt_list_offsets(const int blocks, const int ring, volatile __global int* counters,
                       __global int2* block_sums, __global int* listing)
{
    __local int scratch[COMPACT_SCRATCH_INTS];
    const int lid = get_local_id(0), per_item = (blocks + LOCAL_SIZE - 1) / LOCAL_SIZE;
    const int begin = min(lid * per_item, blocks), end = min(begin + per_item, blocks);
    int2 run = (int2)(0, 0);
    for (int b = begin; b < end; ++b) run += block_sums[b];
    int records, listed;
    int2 start = (int2)(compact_group_scan(run.x, scratch, &records), compact_group_scan(run.y, scratch, &listed));
    for (int b = begin; b < end; ++b) {
        int2 sums = block_sums[b];
        block_sums[b] = start;
        start += sums;
    }
    if (lid == 0) {
        counters[TERMINATED_SAMPLES] -= listed;
        const int lengths = RING_LENGTHS(ring);
        listing[LISTING_LISTED] = listed;
        listing[LISTING_RECORDS] = records;
        listing[LISTING_EYE_LENGTH] = counters[lengths];
        listing[LISTING_LIGHT_LENGTH] = counters[lengths + 1];
        listing[LISTING_WALK_STEPS] = counters[WALK_STEPS];
    }
}

/* firsts[slot]: where the slot's records start (0 records unless listed); listed_slots: the
 * listed slots, in slot order. block_starts: bdpt_list_offsets' scan of the groups' sums. */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void bdpt_list_terminated(const int pool, __global const BdptSlot* slots, __global const int* counts,
                          __global const int2* block_starts, __global int* firsts, __global int* listed_slots)
{
    __local int scratch[COMPACT_SCRATCH_INTS];
    int gid = get_global_id(0);
    bool listed = gid < pool && slots[gid].live == SLOT_CONNECTING;
    int2 start = block_starts[get_group_id(0)];
    int unused;
    int first = start.x + compact_group_scan(listed ? counts[gid] : 0, scratch, &unused);
    int rank = start.y + compact_group_scan(listed ? 1 : 0, scratch, &unused);
    if (gid < pool) firsts[gid] = first;
    if (listed) listed_slots[rank] = gid;
}

#endif
