/* Path tracing on a compacted sample stream with regeneration at the end of the stream
 * (the talk's "Stream Compaction + Regeneration"):
 *   extend  - every path in the stream takes one step (all lanes busy);
 *   compact - paths that ended leave the stream, the survivors are packed at its start;
 *   shadow  - the next-event shadow rays that extend prepared were queued, packed, the same
 *             way; one kernel traces them all (a lane that has no shadow ray never waits);
 *   regenerate - new samples fill the end of the stream, so it keeps its size; they are
 *             consecutive pixels, side by side, so their primary rays are coherent.
 * Compaction is "immediate" (single pass, fused into extend: cl/compact.h) or multi-pass
 * (extend writes alive flags, toolkit/opencl/compaction.py scans, pt_compact_regen_gather moves).
 * Kernels this technique launches (toolkit/techniques/pt_compact_regen.py):
 *   pt_compact_regen_generate    here
 *   pt_compact_regen_extend      here (immediate compaction)
 *   pt_compact_regen_shadow      here (immediate compaction)
 *   extend_in_place              cl/extend_in_place.h (multi-pass compaction; shared with pt_inplace_regen)
 *   the scan                     toolkit/opencl/compaction.py (multi-pass compaction)
 *   pt_compact_regen_gather      here (multi-pass compaction)
 * Every stream is a structure of arrays of `capacity` records in one buffer (layout.h). */
#include "path.h"
#include "compact.h"
#include "extend_in_place.h"

/* Extend + immediate compaction: survivors are written packed into the `out` stream, and
 * the shadow rays they prepared packed into the shadow queue; counters[STREAM_PATHS] and
 * counters[STREAM_SHADOW_RAYS] count them (StreamCounter, toolkit/core/layout.py). */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void pt_compact_regen_extend(SCENE_PARAMS, const uint seed, const int length, const int capacity,
                             __global void* in, __global void* out, __global void* shadow,
                             volatile __global int* counters, __global float4* radiance,
                             __global LaneCounts* lane_counts)
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
        p = path_state_load(path_state_soa(in, capacity), gid);
        alive = path_extend_deferred(&s, &p, seed, &count, &ray);
        if (!alive) path_finish(radiance, &p);
    }
    int slot = immediate_compact_slot(alive, scratch, &counters[STREAM_PATHS]);
    if (slot >= 0) path_state_store(path_state_soa(out, capacity), slot, &p);
    int queued = immediate_compact_slot(ray.slot >= 0, scratch, &counters[STREAM_SHADOW_RAYS]);
    if (queued >= 0) shadow_ray_store(shadow_ray_soa(shadow, capacity), queued, &ray);
#if COUNT_SIMD
    count.shadow_rays = ray.slot >= 0;   /* queued, traced by pt_compact_regen_shadow */
    if (gid < length) lane_counts[gid] = lane_counts_of(1, &count);
#endif
}

/* Trace the queued shadow rays; an unoccluded one adds its contribution to its sample.
 * A sample has at most one shadow ray per iteration, so no two work-items add to one slot. */
__kernel void pt_compact_regen_shadow(SCENE_PARAMS, const int length, const int capacity, __global void* shadow,
                                      __global float4* radiance, __global int* lane_steps)
{
    int gid = get_global_id(0);
    if (gid >= length) return;
    SceneView s = SCENE_INIT;
    ShadowRay ray = shadow_ray_load(shadow_ray_soa(shadow, capacity), gid);
    LaneCounters count = {0, 0, 0};
    if (shadow_unoccluded(&s, &ray, &count))
        radiance[ray.slot].xyz += ray.contribution.xyz;
#if COUNT_SIMD
    lane_steps[gid] = count.shadow_steps;
#endif
}

/* Move the survivors listed in `indices` (from the scan) to the start of the `out` stream. */
__kernel void pt_compact_regen_gather(const int count, __global const int* indices, const int capacity,
                                      __global void* in, __global void* out)
{
    int gid = get_global_id(0);
    if (gid >= count) return;
    PathState p = path_state_load(path_state_soa(in, capacity), indices[gid]);
    path_state_store(path_state_soa(out, capacity), gid, &p);
}

/* Regenerate at the end of the stream: slots first .. first+count-1 start samples
 * first_id .. first_id+count-1 (consecutive pixels). */
__kernel void pt_compact_regen_generate(const Camera cam, const uint seed, const int first,
                                        const int count, const int first_id, const int sample_base,
                                        const int capacity, __global void* out)
{
    int gid = get_global_id(0);
    if (gid >= count) return;
    PathState p;
    path_start_sample(&p, &cam, first_id + gid, sample_base, seed);
    path_state_store(path_state_soa(out, capacity), first + gid, &p);
}
