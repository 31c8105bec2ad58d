/* Assignment 1: in-place sample regeneration (Novak et al. 2010; van Antwerpen, HPG 2011, slide
 * "In-Place Sample Regeneration"). Your file replaces the toolkit's cl/pt_inplace_regen.cl:
 *     python -m toolkit grade inplace_regen --kernel THIS_FILE
 * Each work-item owns one slot of the path stream. Each step, the host launches
 * pt_inplace_regen_trace, which first calls regenerate_slot for every slot (a slot whose path
 * has ended starts the next sample of the pass's budget in place), then traces, and
 * pt_inplace_regen_shade (both given). Fill in the region marked TODO in regenerate_slot; keep
 * its name and arguments, and the kernels below it as they are. */
#include "extend_in_place.h"

/* cam, pass_args->seed, pass_args->sample_base: pass them on to path_start_sample (cl/path.h).
 *               (pass_args is a PtPass record: toolkit/core/layout.py.)
 * pass_args->budget: samples in this pass; sample ids are 0 .. budget - 1.
 * next_sample:  the next sample id to start, shared by all work-items (an atomic counter).
 * paths:        the path states, a structure of arrays of pass_args->capacity records:
 *               path_state_store(path_state_soa(paths, pass_args->capacity), slot, &p) writes slot `slot`.
 * alive:        alive[gid] != 0 while slot gid holds a live path.
 * any_alive:    0 when the step starts; the host stops when it stays 0: set it to 1 if your
 *               slot holds a live path after the regeneration.
 * Returns 1 if this slot started a sample, else 0 (the SIMD counters count those lanes). */
HELPER int regenerate_slot(const Camera* cam, const PtPass* pass_args, volatile __global int* next_sample,
                           __global void* paths, __global int* alive, __global int* any_alive, int gid)
{
    int started = 0;
    /* TODO: if this slot is free, take the next sample id (atomically); if it is inside the
     * budget, start it with path_start_sample, store it in this slot, mark the slot alive and
     * set started. Then tell the host whether the slot holds a live path (any_alive). */
    (void)cam; (void)pass_args; (void)next_sample; (void)paths; (void)alive; (void)any_alive; (void)gid;
    return started;
}

/* The regeneration alone, over `slots` slots (the assignment's checks launch it; the technique
 * regenerates inside pt_inplace_regen_trace). */
__kernel void pt_inplace_regen_regenerate(const Camera cam, const PtPass pass_args, const int slots,
                                          volatile __global int* next_sample,
                                          __global void* paths, __global int* alive,
                                          __global int* any_alive, __global int* regenerated)
{
    int gid = get_global_id(0);
    if (gid >= slots) return;
    int started = regenerate_slot(&cam, &pass_args, next_sample, paths, alive, any_alive, gid);
#if COUNT_SIMD
    regenerated[gid] = started;
#else
    (void)started; (void)regenerated;
#endif
}

/* A step's first launch: regenerate the free slots (only they are busy in that part, the
 * talk's ~30%), then every slot with a live path finds its ray's closest hit (into `hits`).
 * *any_alive is 0 when the launch starts (the last step's shade cleared it). */
__kernel void pt_inplace_regen_trace(SCENE_PARAMS, const Camera cam, const PtPass pass_args, const int slots,
                                     volatile __global int* next_sample, __global void* paths, __global int* alive,
                                     __global void* hits, __global int* any_alive, __global int* regenerated,
                                     __global LaneCounts* lane_counts)
{
    int gid = get_global_id(0);
    if (gid >= slots) return;
    int started = regenerate_slot(&cam, &pass_args, next_sample, paths, alive, any_alive, gid);
#if COUNT_SIMD
    regenerated[gid] = started;
#else
    (void)started; (void)regenerated;
#endif
    SceneView scene = SCENE_INIT;
    trace_in_place(&scene, &pass_args, paths, alive, hits, lane_counts, gid);
}

/* A step's second launch: every slot with a live path shades its hit. Work-item 0 clears
 * *any_alive for the next step's regeneration: the host's look at it (if any) is queued before
 * this launch, and no work-item of this launch sets it. So the host never clears it. */
__kernel void pt_inplace_regen_shade(SCENE_PARAMS, const PtPass pass_args, const int slots,
                                     __global void* paths, __global int* alive, __global void* hits,
                                     __global float4* radiance, __global int* any_alive,
                                     __global LaneCounts* lane_counts)
{
    int gid = get_global_id(0);
    if (gid == 0) *any_alive = 0;
    if (gid >= slots || !alive[gid]) return;
    SceneView scene = SCENE_INIT;
    shade_in_place(&scene, &pass_args, paths, alive, hits, radiance, lane_counts, gid);
}
