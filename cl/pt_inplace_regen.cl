/* Path tracing with in-place sample regeneration (Novak et al. 2010; the talk's
 * "In-Place Sample Regeneration"). Each work-item owns one slot of the path stream.
 * After every extension step, the slots whose path ended start a new sample in place:
 * extension stays busy, but the regeneration runs with only the terminated lanes
 * active (the talk: ~30% active threads per warp).
 * A step is two launches (inside a render each launch costs the host tens of microseconds:
 * results/issue48_launch_path.md): the regeneration runs at the start of the trace kernel.
 * Kernels this technique launches (toolkit/techniques/pt_inplace_regen.py):
 *   pt_inplace_regen_trace        regenerate, then trace (extend's first half)
 *   pt_inplace_regen_shade        shade (extend's second half)
 * and pt_inplace_regen_regenerate, the regeneration alone (the assignment's checks launch it),
 * all three in cl/pt_inplace_regen_kernels.h, around regenerate_slot here. */
#include "extend_in_place.h"

/* Regenerate slot gid in place: if it is free, it takes the next sample of the pass's budget, if
 * any is left. Returns 1 if it started a sample. Sample ids come from one atomic counter; the
 * image does not depend on which slot gets which sample because every random number is keyed by
 * the sample, not by the slot. If the slot holds a live path afterwards it sets *any_alive.
 * `pass_args`: the pass's seed, sample_base, budget and the capacity of `paths` (PtPass, layout.h). */
HELPER int regenerate_slot(const Camera* cam, const PtPass* pass_args, volatile __global int* next_sample,
                           __global void* paths, __global int* alive, __global int* any_alive, int gid)
{
    int started = 0;
    /* The counter is read before it is raised: once the budget is spent it stays put, so it
     * never passes the budget + slots, however many iterations the pass takes (no int overflow).
     * Read atomically (an atomic_add of 0): a plain read of a counter that other work-items
     * atomic_inc meanwhile is a data race, undefined in OpenCL's memory model. The sample is the
     * one atomic_inc returns, tested again: others may have taken the last ones in between. */
    if (!alive[gid] && atomic_add(next_sample, 0) < pass_args->budget) {
        int id = atomic_inc(next_sample);
        if (id < pass_args->budget) {
            PathState p;
            path_start_sample(&p, cam, id, pass_args->sample_base, pass_args->seed);
            path_state_store(path_state_soa(paths, pass_args->capacity), gid, &p);
            alive[gid] = 1;
            started = 1;
        }
    }
    if (alive[gid]) *any_alive = 1;   /* every writer writes the same value */
    return started;
}

/* The kernels that call it: the regeneration alone, and a step's trace and shade. */
#include "pt_inplace_regen_kernels.h"
