/* Path tracing with in-place sample regeneration (Novak et al. 2010; the talk's
 * "In-Place Sample Regeneration"). Each work-item owns one slot of the path stream.
 * After every extension step, the slots whose path ended start a new sample in place:
 * extension stays busy, but the regeneration step runs with only the terminated lanes
 * active (the talk: ~30% active threads per warp).
 * Kernels this technique launches (toolkit/techniques/pt_inplace_regen.py):
 *   pt_inplace_regen_regenerate   here
 *   extend_in_place_trace         cl/extend_in_place.h (shared with pt_compact_regen)
 *   extend_in_place_shade         cl/extend_in_place.h (shared with pt_compact_regen) */
#include "extend_in_place.h"

/* Regenerate in place: a free slot takes the next sample of the pass's budget, if any is left.
 * Sample ids come from one atomic counter; the image does not depend on which slot gets
 * which sample because every random number is keyed by the sample, not by the slot.
 * Any slot that holds a live path afterwards sets *any_alive (the host clears it first).
 * `pass_args`: the pass's seed, sample_base, budget and the capacity of `paths` (PtPass, layout.h). */
__kernel void pt_inplace_regen_regenerate(const Camera cam, const PtPass pass_args, const int slots,
                                          volatile __global int* next_sample,
                                          __global void* paths, __global int* alive,
                                          __global int* any_alive, __global int* regenerated)
{
    int gid = get_global_id(0);
    if (gid >= slots) return;
    int started = 0;
    /* The counter is read before it is raised: once the budget is spent it stays put, so it
     * never passes the budget + slots, however many iterations the pass takes (no int overflow).
     * Read atomically (an atomic_add of 0): a plain read of a counter that other work-items
     * atomic_inc meanwhile is a data race, undefined in OpenCL's memory model. The sample is the
     * one atomic_inc returns, tested again: others may have taken the last ones in between. */
    if (!alive[gid] && atomic_add(next_sample, 0) < pass_args.budget) {
        int id = atomic_inc(next_sample);
        if (id < pass_args.budget) {
            PathState p;
            path_start_sample(&p, &cam, id, pass_args.sample_base, pass_args.seed);
            path_state_store(path_state_soa(paths, pass_args.capacity), gid, &p);
            alive[gid] = 1;
            started = 1;
        }
    }
    if (alive[gid]) *any_alive = 1;   /* every writer writes the same value */
#if COUNT_SIMD
    regenerated[gid] = started;
#endif
}
