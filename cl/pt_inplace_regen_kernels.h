/* pt_inplace_regen's kernels around regenerate_slot (cl/pt_inplace_regen.cl, or a student's file
 * of the inplace_regen assignment, defines it before including this): the regeneration alone, and a
 * step's two launches. Kept here once, so the technique, the assignment's stub and its graded
 * fixtures launch the same kernels. */
#ifndef PT_INPLACE_REGEN_KERNELS_H
#define PT_INPLACE_REGEN_KERNELS_H

/* Slot gid's regeneration (regenerate_slot), and with COUNT_SIMD whether it started a sample. */
HELPER void regenerate_and_note(const Camera* cam, const PtPass* pass_args, volatile __global int* next_sample,
                                __global void* paths, __global int* alive, __global int* any_alive,
                                __global int* regenerated, int gid)
{
    int started = regenerate_slot(cam, pass_args, next_sample, paths, alive, any_alive, gid);
#if COUNT_SIMD
    regenerated[gid] = started;
#else
    (void)started; (void)regenerated;
#endif
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
    regenerate_and_note(&cam, &pass_args, next_sample, paths, alive, any_alive, regenerated, gid);
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
    regenerate_and_note(&cam, &pass_args, next_sample, paths, alive, any_alive, regenerated, gid);
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

#endif
