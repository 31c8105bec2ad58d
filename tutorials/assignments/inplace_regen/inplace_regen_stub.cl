/* Assignment 1: in-place sample regeneration (Novak et al. 2010; van Antwerpen, HPG 2011, slide
 * "In-Place Sample Regeneration"). Your file replaces the toolkit's cl/pt_inplace_regen.cl:
 *     python -m toolkit grade inplace_regen --kernel THIS_FILE
 * Each work-item owns one slot of the path stream. Each step, the host launches
 * pt_inplace_regen_trace, which first calls regenerate_slot for every slot (a slot whose path
 * has ended starts the next sample of the pass's budget in place), then traces, and
 * pt_inplace_regen_shade (both given, in cl/pt_inplace_regen_kernels.h). Fill in the region
 * marked TODO in regenerate_slot; keep its name and arguments, and the #include at the end. */
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

/* The kernels that call it: the regeneration alone, and a step's trace and shade. */
#include "pt_inplace_regen_kernels.h"
