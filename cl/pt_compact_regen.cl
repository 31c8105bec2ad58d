/* Path tracing on a compacted sample stream with regeneration at the end of the stream
 * (the talk's "Stream Compaction + Regeneration"):
 *   extend  - every path in the stream takes one step (all lanes busy), in two kernels (a
 *             wavefront path tracer: Laine, Karras and Aila 2013, "Megakernels considered
 *             harmful"): trace finds each ray's closest hit and writes a small hit record, then
 *             shade reads it (emission, next-event estimation, BSDF sampling, roulette). So
 *             the BVH loop, where lanes wait for each other, runs in a short kernel of its own,
 *             and shading in one that never traverses;
 *   compact - paths that ended leave the stream, the survivors are packed at its start;
 *   shadow  - the next-event shadow rays that shade prepared were queued, packed, the same
 *             way; one kernel traces them all (a lane that has no shadow ray never waits);
 *   regenerate - new samples fill the end of the stream, so it keeps its size; they are
 *             consecutive pixels, side by side, so their primary rays are coherent.
 * Compaction is "immediate" (single pass, fused into shade: cl/compact.h) or multi-pass
 * (extend_in_place_trace and _shade take the step in place and write alive flags,
 * toolkit/opencl/compaction.py scans, pt_compact_regen_gather moves).
 * Kernels this technique launches (toolkit/techniques/pt_compact_regen.py):
 *   pt_compact_regen_generate    here
 *   pt_compact_regen_trace       here (immediate compaction)
 *   pt_compact_regen_shade       here (immediate compaction: shade + compact)
 *   pt_compact_regen_shadow      here (immediate compaction)
 *   extend_in_place_trace        cl/extend_in_place.h (multi-pass compaction; shared with pt_inplace_regen)
 *   extend_in_place_shade        cl/extend_in_place.h (multi-pass compaction; shared with pt_inplace_regen)
 *   the scan                     toolkit/opencl/compaction.py (multi-pass compaction)
 *   pt_compact_regen_gather      here (multi-pass compaction)
 * Every stream is a structure of arrays of pass_args.capacity records in one buffer (layout.h);
 * `pass_args` (PtPass) holds what every kernel of the pass shares. */
#include "path.h"
#include "compact.h"
#include "extend_in_place.h"

/* Trace: the closest hit of each stream entry's ray, into the hit stream (HitRecord, layout.h). */
__kernel void pt_compact_regen_trace(SCENE_PARAMS, const PtPass pass_args, const int stream_length,
                                     __global void* stream, __global void* hits, __global LaneCounts* lane_counts)
{
    int gid = get_global_id(0);
    if (gid >= stream_length) return;
    SceneView scene = SCENE_INIT;
    LaneCounters count = {0, 0, 0};
    path_trace_entry(&scene, path_state_soa(stream, pass_args.capacity), hit_record_soa(hits, pass_args.capacity),
                     gid, &count);
#if COUNT_SIMD
    lane_counts[gid] = lane_counts_of(1, &count);   /* its traversal steps; shade adds the rest */
#endif
}

/* Shade the hits that trace found + immediate compaction: survivors are written packed into
 * `next_stream`, and the shadow rays they prepared packed into the shadow queue;
 * counters[STREAM_PATHS] and counters[STREAM_SHADOW_RAYS] count them (StreamCounter,
 * toolkit/core/layout.py). */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void pt_compact_regen_shade(SCENE_PARAMS, const PtPass pass_args, const int stream_length,
                             __global void* stream, __global void* hits, __global void* next_stream,
                             __global void* shadow_rays, volatile __global int* counters, __global float4* radiance,
                             __global LaneCounts* lane_counts)
{
    int gid = get_global_id(0);
    __local int scratch[COMPACT_SCRATCH_INTS];
    PathState p;
    ShadowRay ray;
    ray.slot = -1;
    bool alive = false;
    /* No early return: every work-item of the group must reach the compaction barriers. */
    if (gid < stream_length) {
        SceneView scene = SCENE_INIT;
        p = path_state_load(path_state_soa(stream, pass_args.capacity), gid);
        HitRecord hit = hit_record_load(hit_record_soa(hits, pass_args.capacity), gid);
        alive = path_shade_deferred(&scene, &p, hit, pass_args.seed, &ray);
        if (!alive) path_finish(radiance, &p);
    }
    int slot = immediate_compact_slot(alive, scratch, &counters[STREAM_PATHS]);
    if (slot >= 0) path_state_store(path_state_soa(next_stream, pass_args.capacity), slot, &p);
    int queued = immediate_compact_slot(ray.slot >= 0, scratch, &counters[STREAM_SHADOW_RAYS]);
    if (queued >= 0) shadow_ray_store(shadow_ray_soa(shadow_rays, pass_args.capacity), queued, &ray);
#if COUNT_SIMD
    /* trace wrote this lane's record; the shadow ray was queued, traced by pt_compact_regen_shadow */
    if (gid < stream_length) lane_counts[gid].shadow_rays = ray.slot >= 0;
#endif
}

/* Trace the queued shadow rays; an unoccluded one adds its contribution to its sample.
 * A sample has at most one shadow ray per iteration, so no two work-items add to one slot. */
__kernel void pt_compact_regen_shadow(SCENE_PARAMS, const PtPass pass_args, const int queued,
                                      __global void* shadow_rays, __global float4* radiance,
                                      __global int* shadow_steps)
{
    int gid = get_global_id(0);
    if (gid >= queued) return;
    SceneView scene = SCENE_INIT;
    ShadowRay ray = shadow_ray_load(shadow_ray_soa(shadow_rays, pass_args.capacity), gid);
    LaneCounters count = {0, 0, 0};
    if (shadow_unoccluded(&scene, &ray, &count))
        radiance[ray.slot].xyz += ray.contribution.xyz;
#if COUNT_SIMD
    shadow_steps[gid] = count.shadow_steps;
#endif
}

/* Move the survivors listed in `indices` (from the scan) to the start of `next_stream`. */
__kernel void pt_compact_regen_gather(const PtPass pass_args, const int count, __global const int* indices,
                                      __global void* stream, __global void* next_stream)
{
    int gid = get_global_id(0);
    if (gid >= count) return;
    PathState p = path_state_load(path_state_soa(stream, pass_args.capacity), indices[gid]);
    path_state_store(path_state_soa(next_stream, pass_args.capacity), gid, &p);
}

/* Regenerate at the end of the stream: entries r.base .. r.base + r.count - 1 start samples
 * r.first_id .. r.first_id + r.count - 1 (consecutive pixels; PtRegeneration, layout.h). */
__kernel void pt_compact_regen_generate(const Camera cam, const PtPass pass_args, const PtRegeneration r,
                                        __global void* stream)
{
    int gid = get_global_id(0);
    if (gid >= r.count) return;
    PathState p;
    path_start_sample(&p, &cam, r.first_id + gid, pass_args.sample_base, pass_args.seed);
    path_state_store(path_state_soa(stream, pass_args.capacity), r.base + gid, &p);
}
