/* Grader kernels of assignment 1 (toolkit/grading/checks/compaction.py): the toolkit's compaction kernels
 * (cl/compact.cl: scan_blocks, compact_immediate) built with the student's compact.h, and one
 * kernel that compacts twice in a row, as pt_compact_regen_extend does (paths, then shadow rays).
 * Every atomic_add / atomic_inc on a counter also counts itself in the int after the counter,
 * so the grader can tell one atomic per work-group from one per survivor. */
__attribute__((overloadable)) static inline int grade_atomic_add(volatile __global int* p, int v) { atomic_inc(p + 1); return atomic_add(p, v); }
__attribute__((overloadable)) static inline int grade_atomic_inc(volatile __global int* p) { atomic_inc(p + 1); return atomic_inc(p); }
__attribute__((overloadable)) static inline int grade_atomic_add(volatile __local int* p, int v) { return atomic_add(p, v); }
__attribute__((overloadable)) static inline int grade_atomic_inc(volatile __local int* p) { return atomic_inc(p); }
#undef atomic_add
#undef atomic_inc
#define atomic_add grade_atomic_add
#define atomic_inc grade_atomic_inc

#include "compact.cl"

__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void grade_compact_twice(__global const int* flags_a, __global const int* flags_b, const int n,
                         volatile __global int* counters, __global int* out_a, __global int* out_b)
{
    __local int scratch[COMPACT_SCRATCH_INTS];
    int gid = get_global_id(0);
    bool a = gid < n && flags_a[gid] != 0;
    bool b = gid < n && flags_b[gid] != 0;
    int slot_a = immediate_compact_slot(a, scratch, &counters[0]);
    int slot_b = immediate_compact_slot(b, scratch, &counters[2]);
    if (slot_a >= 0) out_a[slot_a] = gid;
    if (slot_b >= 0) out_b[slot_b] = gid;
}
