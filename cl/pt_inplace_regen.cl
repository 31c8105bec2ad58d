/* Path tracing with in-place sample regeneration (Novak et al. 2010; the talk's
 * "In-Place Sample Regeneration"). Each work-item owns one slot of the path stream.
 * After every extension step, the slots whose path ended start a new sample in place:
 * extension stays busy, but the regeneration step runs with only the terminated lanes
 * active (the talk: ~30% active threads per warp). */
#include "path.h"

/* Extend every live path by one vertex; a path that ends writes its radiance and frees its slot. */
__kernel void pt_inplace_regen_extend(SCENE_PARAMS, const uint seed, const int slots,
                                      PATH_STATE_SOA_PARAMS(path), __global int* alive,
                                      __global float4* radiance, __global int4* lane_counts)
{
    int gid = get_global_id(0);
    if (gid >= slots) return;
    LaneCounters count = {0, 0, 0};
    int was_alive = alive[gid];
    if (was_alive) {
        SceneView s = SCENE_INIT;
        alive[gid] = path_extend_in_place(&s, PATH_STATE_SOA(path), gid, seed, &count, radiance);
    }
#if COUNT_SIMD
    lane_counts[gid] = (int4)(was_alive, count.traversal_steps, count.shadow_rays, count.shadow_steps);
#endif
}

/* Regenerate in place: a free slot takes the next sample of the pass's budget, if any is left.
 * Sample ids come from one atomic counter; the image does not depend on which slot gets
 * which sample because every random number is keyed by the sample, not by the slot. */
__kernel void pt_inplace_regen_regenerate(const Camera cam, const uint seed, const int slots,
                                          const int sample_base, const int budget,
                                          volatile __global int* next_sample,
                                          PATH_STATE_SOA_PARAMS(path), __global int* alive,
                                          __global int* regenerated)
{
    int gid = get_global_id(0);
    if (gid >= slots) return;
    int started = 0;
    if (!alive[gid]) {
        int id = atomic_inc(next_sample);
        if (id < budget) {
            PathState p;
            path_start_sample(&p, &cam, id, sample_base, seed);
            path_state_store(PATH_STATE_SOA(path), gid, &p);
            alive[gid] = 1;
            started = 1;
        }
    }
#if COUNT_SIMD
    regenerated[gid] = started;
#endif
}
