/* Path tracing on a compacted sample stream with regeneration at the end of the stream
 * (the talk's "Stream Compaction + Regeneration"):
 *   extend  - every path in the stream takes one step (all lanes busy);
 *   compact - paths that ended leave the stream, the survivors are packed at its start;
 *   shadow  - the next-event shadow rays that extend prepared were queued, packed, the same
 *             way; one kernel traces them all (a lane that has no shadow ray never waits);
 *   regenerate - new samples fill the end of the stream, so it keeps its size; they are
 *             consecutive pixels, side by side, so their primary rays are coherent.
 * Compaction is "immediate" (single pass, fused into extend: cl/compact.h) or multi-pass
 * (extend writes alive flags, toolkit/compaction.py scans, pt_compact_regen_gather moves). */
#include "path.h"
#include "compact.h"

/* Extend + immediate compaction: survivors are written packed into the `out` stream, and
 * the shadow rays they prepared packed into the shadow queue. */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void pt_compact_regen_extend(SCENE_PARAMS, const uint seed, const int length,
                             PATH_STATE_SOA_PARAMS(in), PATH_STATE_SOA_PARAMS(out),
                             volatile __global int* out_length,
                             SHADOW_RAY_SOA_PARAMS(shadow), volatile __global int* shadow_length,
                             __global float4* radiance, __global int4* lane_counts)
{
    int gid = get_global_id(0);
    __local int scratch[COMPACT_SCRATCH_INTS];
    LaneCounters count = {0, 0, 0};
    PathState p;
    ShadowRay ray;
    ray.slot = -1;
    bool alive = false;
    /* No early return: every work-item of the group must reach the compaction barriers. */
    if (gid < length) {
        SceneView s = SCENE_INIT;
        p = path_state_load(PATH_STATE_SOA(in), gid);
        alive = path_extend_deferred(&s, &p, seed, &count, &ray);
        if (!alive) path_finish(radiance, &p);
    }
    int slot = immediate_compact_slot(alive, scratch, out_length);
    if (slot >= 0) path_state_store(PATH_STATE_SOA(out), slot, &p);
    int queued = immediate_compact_slot(ray.slot >= 0, scratch, shadow_length);
    if (queued >= 0) shadow_ray_store(SHADOW_RAY_SOA(shadow), queued, &ray);
#if COUNT_SIMD
    if (gid < length) lane_counts[gid] = (int4)(1, count.traversal_steps, ray.slot >= 0, 0);
#endif
}

/* Trace the queued shadow rays; an unoccluded one adds its contribution to its sample.
 * A sample has at most one shadow ray per iteration, so no two work-items add to one slot. */
__kernel void pt_compact_regen_shadow(SCENE_PARAMS, const int length, SHADOW_RAY_SOA_PARAMS(shadow),
                                      __global float4* radiance, __global int* lane_steps)
{
    int gid = get_global_id(0);
    if (gid >= length) return;
    SceneView s = SCENE_INIT;
    ShadowRay ray = shadow_ray_load(SHADOW_RAY_SOA(shadow), gid);
    LaneCounters count = {0, 0, 0};
    if (shadow_unoccluded(&s, &ray, &count))
        radiance[ray.slot].xyz += ray.contribution.xyz;
#if COUNT_SIMD
    lane_steps[gid] = count.shadow_steps;
#endif
}

/* Extend in place and label the survivors: the first half of multi-pass compaction.
 * (This variant traces its shadow rays inline: it exists to compare compaction methods.) */
__kernel void pt_compact_regen_extend_flags(SCENE_PARAMS, const uint seed, const int length,
                                            PATH_STATE_SOA_PARAMS(path), __global int* alive,
                                            __global float4* radiance, __global int4* lane_counts)
{
    int gid = get_global_id(0);
    if (gid >= length) return;
    LaneCounters count = {0, 0, 0};
    SceneView s = SCENE_INIT;
    alive[gid] = path_extend_in_place(&s, PATH_STATE_SOA(path), gid, seed, &count, radiance);
#if COUNT_SIMD
    lane_counts[gid] = (int4)(1, count.traversal_steps, count.shadow_rays, count.shadow_steps);
#endif
}

/* Move the survivors listed in `indices` (from the scan) to the start of the `out` stream. */
__kernel void pt_compact_regen_gather(const int count, __global const int* indices,
                                      PATH_STATE_SOA_PARAMS(in), PATH_STATE_SOA_PARAMS(out))
{
    int gid = get_global_id(0);
    if (gid >= count) return;
    PathState p = path_state_load(PATH_STATE_SOA(in), indices[gid]);
    path_state_store(PATH_STATE_SOA(out), gid, &p);
}

/* Regenerate at the end of the stream: slots first .. first+count-1 start samples
 * first_id .. first_id+count-1 (consecutive pixels). */
__kernel void pt_compact_regen_generate(const Camera cam, const uint seed, const int first,
                                        const int count, const int first_id, const int sample_base,
                                        PATH_STATE_SOA_PARAMS(out))
{
    int gid = get_global_id(0);
    if (gid >= count) return;
    PathState p;
    path_start_sample(&p, &cam, first_id + gid, sample_base, seed);
    path_state_store(PATH_STATE_SOA(out), first + gid, &p);
}
