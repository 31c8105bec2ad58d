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
 *   pt_compact_regen_generate    here (multi-pass compaction)
 *   pt_compact_regen_trace       here (immediate compaction: the last step's shadow rays + regenerate + trace)
 *   pt_compact_regen_shade       here (immediate compaction: shade + compact)
 *   extend_in_place_trace        here (multi-pass compaction; its body shared with pt_inplace_regen: extend_in_place.h)
 *   extend_in_place_shade        here (multi-pass compaction; likewise)
 *   the scan                     toolkit/opencl/compaction.py (multi-pass compaction)
 *   pt_compact_regen_gather      here (multi-pass compaction)
 * Every stream is a structure of arrays of pass_args.capacity records in one buffer (layout.h);
 * `pass_args` (PtPass) holds what every kernel of the pass shares.
 *
 * The counts stay on the device (pbrt-v4's work queues do the same): each step's PtStep record
 * (layout.h) holds the stream's length, the survivors and queued shadow rays that compaction
 * counts, and the next sample to start. Every kernel is launched over the whole stream
 * (stream_size work-items) and a work-item past the step's count returns at once, so the host
 * never waits for a count before the next launch; it reads a step's record only now and then,
 * to learn that the pass is over (toolkit/techniques/pass_end.py). */
#include "path.h"
#include "compact.h"
#include "extend_in_place.h"

/* Regenerate at the end of the stream: the last step left last_counts->survivors paths packed at
 * its start; entries survivors .. survivors + count - 1 start the next `count` samples of the
 * budget (consecutive pixels), as many as fit in the stream's `stream_size` entries. Returns
 * whether work-item `gid` started a sample, and sets *length to the stream's length this step.
 * Every work-item reads only last_counts; work-item 0 alone writes this step's record (its length,
 * the next sample, and compaction's counters set to zero), so no work-item of the launch reads
 * what another writes: each computes the length itself. */
HELPER bool regenerate_entry(const Camera* cam, const PtPass* pass_args, int stream_size,
                             __global const PtStep* last_counts, __global PtStep* counts,
                             __global void* stream, int gid, int* length)
{
    int survivors = last_counts->survivors, first_id = last_counts->next_sample;
    int count = min(stream_size - survivors, pass_args->budget - first_id);
    *length = survivors + count;
    if (gid == 0) {
        counts->length = survivors + count;
        counts->started = count;
        counts->next_sample = first_id + count;
        counts->survivors = 0;
        counts->shadow_rays = 0;
    }
    if (gid < survivors || gid >= survivors + count) return false;
    PathState p;
    path_start_sample(&p, cam, first_id + gid - survivors, pass_args->sample_base, pass_args->seed);
    path_state_store(path_state_soa(stream, pass_args->capacity), gid, &p);
    return true;
}

/* Regeneration alone (multi-pass compaction, whose extension is extend_in_place_*): a new
 * entry's alive flag is set, as the in-place extension reads the flags (gather set the survivors'). */
__kernel void pt_compact_regen_generate(const Camera cam, const PtPass pass_args, const int stream_size,
                                        __global const PtStep* last_counts, __global PtStep* counts,
                                        __global void* stream, __global int* alive)
{
    int gid = get_global_id(0);
    if (gid >= stream_size) return;
    int length;
    if (regenerate_entry(&cam, &pass_args, stream_size, last_counts, counts, stream, gid, &length))
        alive[gid] = 1;
}

/* Trace queued shadow ray `gid`; an unoccluded one adds its contribution to its sample. A sample
 * has at most one shadow ray per step, so no two work-items add to one slot. */
HELPER void trace_queued_shadow_ray(const SceneView* scene, const PtPass* pass_args, __global void* shadow_rays,
                                    __global float4* radiance, int gid, LaneCounters* count)
{
    ShadowRay ray = shadow_ray_load(shadow_ray_soa(shadow_rays, pass_args->capacity), gid);
    if (shadow_unoccluded(scene, &ray, count))
        radiance[ray.slot].xyz += ray.contribution.xyz;
}

/* One launch for the start of a step (immediate compaction; the host's work per step is its
 * launches: results/issue48_launch_path.md):
 *   - the last step's shadow rays (its packed queue, last_counts->shadow_rays of them). A
 *     sample's additions come in order (its shade, then its shadow ray, then the next shade);
 *   - regeneration: a work-item past the last step's survivors starts its entry's sample;
 *   - trace: the closest hit of each entry's ray, into the hit stream (HitRecord, layout.h).
 * A new path goes through the stream's memory as it would between two kernels.
 * SIMD counters: every work-item of the launch writes its LaneCounts, the entries past the
 * stream's length with no work, and .shadow_steps is the queued shadow ray's traversal (the
 * queue is packed from entry 0, as the stream is): so one sum of the launch's lanes counts the
 * step's extension and the last step's shadow queue (pt_compact_regen.py PassCount). */
__kernel void pt_compact_regen_trace(SCENE_PARAMS, const Camera cam, const PtPass pass_args, const int stream_size,
                                     __global const PtStep* last_counts, __global PtStep* counts,
                                     __global void* stream, __global void* hits, __global void* shadow_rays,
                                     __global float4* radiance, __global LaneCounts* lane_counts)
{
    int gid = get_global_id(0);
    if (gid >= stream_size) return;
    SceneView scene = SCENE_INIT;
    LaneCounters queued = {0, 0, 0}, count = {0, 0, 0};
    if (gid < last_counts->shadow_rays)
        trace_queued_shadow_ray(&scene, &pass_args, shadow_rays, radiance, gid, &queued);
    int length;
    regenerate_entry(&cam, &pass_args, stream_size, last_counts, counts, stream, gid, &length);
    if (gid < length)
        path_trace_entry(&scene, path_state_soa(stream, pass_args.capacity), hit_record_soa(hits, pass_args.capacity),
                         gid, &count);
#if COUNT_SIMD
    LaneCounts lane = lane_counts_of(gid < length, &count);   /* its traversal steps; shade adds its shadow ray */
    lane.shadow_steps = queued.shadow_steps;
    lane_counts[gid] = lane;
#endif
}

/* Shade the hits that trace found + immediate compaction: survivors are written packed into
 * `next_stream`, and the shadow rays they prepared packed into the shadow queue;
 * counts->survivors and counts->shadow_rays count them (PtStep, layout.h). */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void pt_compact_regen_shade(SCENE_PARAMS, const PtPass pass_args, __global PtStep* counts,
                             __global void* stream, __global void* hits, __global void* next_stream,
                             __global void* shadow_rays, __global float4* radiance, __global LaneCounts* lane_counts)
{
    int gid = get_global_id(0);
    int length = counts->length;
    /* A work-group wholly past the stream's length leaves at once: all its work-items together,
     * so none of them waits at a barrier the others skip. */
    if (get_group_id(0) * get_local_size(0) >= length) return;
    __local int scratch[COMPACT_SCRATCH_INTS];
    PathState p;
    ShadowRay ray;
    ray.slot = -1;
    bool alive = false;
    /* No early return past this point: every work-item of the group must reach the compaction barriers. */
    if (gid < length) {
        SceneView scene = SCENE_INIT;
        p = path_state_load(path_state_soa(stream, pass_args.capacity), gid);
        HitRecord hit = hit_record_load(hit_record_soa(hits, pass_args.capacity), gid);
        alive = path_shade_deferred(&scene, &p, hit, pass_args.seed, &ray);
        if (!alive) path_finish(radiance, &p);
    }
    int slot = immediate_compact_slot(alive, scratch, &counts->survivors);
    if (slot >= 0) path_state_store(path_state_soa(next_stream, pass_args.capacity), slot, &p);
    int queued = immediate_compact_slot(ray.slot >= 0, scratch, &counts->shadow_rays);
    if (queued >= 0) shadow_ray_store(shadow_ray_soa(shadow_rays, pass_args.capacity), queued, &ray);
#if COUNT_SIMD
    /* trace wrote this lane's record; the shadow ray was queued, traced by the next step's trace */
    if (gid < length) lane_counts[gid].shadow_rays = ray.slot >= 0;
#endif
}

/* The in-place extension step of multi-pass compaction (cl/extend_in_place.h): the entries whose
 * alive flag is set trace, then shade, in place. */
__kernel void extend_in_place_trace(SCENE_PARAMS, const PtPass pass_args, const int stream_length,
                                    __global void* paths, __global const int* alive, __global void* hits,
                                    __global LaneCounts* lane_counts)
{
    int gid = get_global_id(0);
    if (gid >= stream_length) return;
    SceneView scene = SCENE_INIT;
    trace_in_place(&scene, &pass_args, paths, alive, hits, lane_counts, gid);
}

__kernel void extend_in_place_shade(SCENE_PARAMS, const PtPass pass_args, const int stream_length,
                                    __global void* paths, __global int* alive, __global void* hits,
                                    __global float4* radiance, __global LaneCounts* lane_counts)
{
    int gid = get_global_id(0);
    if (gid >= stream_length || !alive[gid]) return;
    SceneView scene = SCENE_INIT;
    shade_in_place(&scene, &pass_args, paths, alive, hits, radiance, lane_counts, gid);
}

/* Move the survivors listed in `indices` (from the scan; *survivors of them, the scan's total)
 * to the start of `next_stream`, count them in the step's record, and set the alive flags of the
 * launch's entries to what the next stream holds (regeneration adds its new entries). The scan
 * and the scatter have read the flags already; gather reads only `indices`. */
__kernel void pt_compact_regen_gather(const PtPass pass_args, __global const int* survivors,
                                      __global const int* indices, __global void* stream, __global void* next_stream,
                                      __global PtStep* counts, __global int* alive)
{
    int gid = get_global_id(0);
    int count = *survivors;
    if (gid == 0) counts->survivors = count;
    alive[gid] = gid < count;    /* every launched work-item: the flags buffer is padded like the launch */
    if (gid >= count) return;
    PathState p = path_state_load(path_state_soa(stream, pass_args.capacity), indices[gid]);
    path_state_store(path_state_soa(next_stream, pass_args.capacity), gid, &p);
}
