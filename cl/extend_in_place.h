/* The in-place extension step, shared by pt_inplace_regen and pt_compact_regen's multi-pass
 * compaction: each work-item owns slot gid of a path stream and, if its path is alive,
 * extends it by one vertex. A path that ends writes its sample's value and clears alive[gid];
 * the flags are then what regeneration (pt_inplace_regen) or the scan of multi-pass compaction
 * (pt_compact_regen) reads.
 *
 * The step is two kernels, as pt_compact_regen's immediate compaction does it (a wavefront split,
 * Laine, Karras and Aila 2013): the trace kernel finds the closest hit of each live slot's ray
 * into a HitRecord stream (trace_in_place), the shade kernel shades it (shade_in_place: emission,
 * the shadow ray traced inline, BSDF sample, roulette). Where work-items run as SIMD lanes, the
 * traversal loop then runs without the shading state around it (measured:
 * results/issue22_lanes.md). Same image as one kernel: the same steps in the same order. The
 * kernels are the techniques' own: pt_inplace_regen's regenerate at the start of the trace
 * kernel (cl/pt_inplace_regen.cl), multi-pass compaction's do the step alone
 * (extend_in_place_trace and _shade, cl/pt_compact_regen.cl).
 * `paths`, `hits`: structures of arrays of pass_args.capacity records (layout.h); the first
 * `stream_length` slots take the step. */
#ifndef EXTEND_IN_PLACE_H
#define EXTEND_IN_PLACE_H

#include "path.h"

/* Slot gid's part of the trace kernel: if its path is alive, the closest hit of its ray into `hits`.
 * pt_inplace_regen's trace kernel calls it after regenerating (cl/pt_inplace_regen.cl). */
HELPER void trace_in_place(const SceneView* scene, const PtPass* pass_args, __global void* paths,
                           __global const int* alive, __global void* hits, __global LaneCounts* lane_counts, int gid)
{
    LaneCounters count = {0, 0, 0};
    int was_alive = alive[gid];
    if (was_alive)
        path_trace_entry(scene, path_state_soa(paths, pass_args->capacity), hit_record_soa(hits, pass_args->capacity),
                         gid, &count);
#if COUNT_SIMD
    lane_counts[gid] = lane_counts_of(was_alive, &count);   /* its traversal steps; shade adds the rest */
#endif
}

/* Slot gid's part of the shade kernel (its path is alive): emission, the shadow ray traced inline,
 * BSDF sample, roulette; a path that ends writes its sample's value and clears alive[gid]. */
HELPER void shade_in_place(const SceneView* scene, const PtPass* pass_args, __global void* paths, __global int* alive,
                           __global void* hits, __global float4* radiance, __global LaneCounts* lane_counts, int gid)
{
    LaneCounters count = {0, 0, 0};
    PathStateSoA soa = path_state_soa(paths, pass_args->capacity);
    PathState p = path_state_load(soa, gid);
    ShadowRay shadow;
    bool continues = path_shade_deferred(scene, &p, hit_record_load(hit_record_soa(hits, pass_args->capacity), gid),
                                         pass_args->seed, &shadow);
    if (shadow.slot >= 0 && shadow_unoccluded(scene, &shadow, &count)) p.radiance.xyz += shadow.contribution.xyz;
    if (continues) path_state_store(soa, gid, &p);
    else path_finish(radiance, &p);
    alive[gid] = continues;
#if COUNT_SIMD
    lane_counts[gid].shadow_rays = count.shadow_rays;
    lane_counts[gid].shadow_steps = count.shadow_steps;
#endif
}

#endif
