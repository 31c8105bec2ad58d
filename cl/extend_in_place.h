/* The in-place extension step, shared by pt_inplace_regen and pt_compact_regen's multi-pass
 * compaction: each work-item owns slot gid of a path stream and, if its path is alive,
 * extends it by one vertex (shadow ray traced inline). A path that ends writes its sample's
 * value and clears alive[gid]; the flags are then what regeneration (pt_inplace_regen) or the
 * scan of multi-pass compaction (pt_compact_regen) reads. */
#ifndef EXTEND_IN_PLACE_H
#define EXTEND_IN_PLACE_H

#include "path.h"

/* `paths`: a PathState structure of arrays of pass_args.capacity records (layout.h); its first
 * `stream_length` slots take the step. */
__kernel void extend_in_place(SCENE_PARAMS, const PtPass pass_args, const int stream_length,
                              __global void* paths, __global int* alive, __global float4* radiance,
                              __global LaneCounts* lane_counts)
{
    int gid = get_global_id(0);
    if (gid >= stream_length) return;
    LaneCounters count = {0, 0, 0};
    int was_alive = alive[gid];
    if (was_alive) {
        SceneView s = SCENE_INIT;
        alive[gid] = path_extend_in_place(&s, path_state_soa(paths, pass_args.capacity), gid, pass_args.seed,
                                          &count, radiance);
    }
#if COUNT_SIMD
    lane_counts[gid] = lane_counts_of(was_alive, &count);
#endif
}

#endif
