/* Assignment 1: in-place sample regeneration (Novak et al. 2010; van Antwerpen, HPG 2011, slide
 * "In-Place Sample Regeneration"). Your file replaces the toolkit's cl/pt_inplace_regen.cl:
 *     python -m toolkit grade inplace_regen --kernel THIS_FILE
 * Each work-item owns one slot of the path stream. After every extension step
 * (extend_in_place_trace and _shade, given), the host runs pt_inplace_regen_regenerate over all slots: a slot
 * whose path has ended starts the next sample of the pass's budget in place.
 * Fill in the region marked TODO; keep the kernel's name and arguments. */
#include "extend_in_place.h"

/* cam, pass_args.seed, pass_args.sample_base: pass them on to path_start_sample (cl/path.h).
 *               (pass_args is a PtPass record: toolkit/core/layout.py.)
 * slots:        slots in the pool (work-items: gid < slots).
 * pass_args.budget: samples in this pass; sample ids are 0 .. budget - 1.
 * next_sample:  the next sample id to start, shared by all work-items (an atomic counter).
 * paths:        the path states, a structure of arrays of pass_args.capacity records:
 *               path_state_store(path_state_soa(paths, pass_args.capacity), slot, &p) writes slot `slot`.
 * alive:        alive[gid] != 0 while slot gid holds a live path.
 * any_alive:    the host clears it before the launch and stops when it stays 0: set it to 1 if
 *               your slot holds a live path after this step.
 * regenerated:  (SIMD counters) 1 in the lanes that started a sample, else 0. */
__kernel void pt_inplace_regen_regenerate(const Camera cam, const PtPass pass_args, const int slots,
                                          volatile __global int* next_sample,
                                          __global void* paths, __global int* alive,
                                          __global int* any_alive, __global int* regenerated)
{
    int gid = get_global_id(0);
    if (gid >= slots) return;
    int started = 0;
    /* TODO: if this slot is free, take the next sample id (atomically); if it is inside the
     * budget, start it with path_start_sample, store it in this slot, mark the slot alive and
     * set started. Then tell the host whether the slot holds a live path (any_alive). */
    (void)cam; (void)pass_args; (void)next_sample; (void)paths; (void)alive; (void)any_alive;
#if COUNT_SIMD
    regenerated[gid] = started;
#else
    (void)regenerated; (void)started;
#endif
}
