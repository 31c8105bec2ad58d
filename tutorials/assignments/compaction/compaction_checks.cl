/* Grader kernels of assignment 2 (toolkit/grading/checks/compaction.py): the toolkit's compaction kernels
 * (cl/compact.cl: scan_blocks, compact_immediate) built with the student's compact.h, and one
 * kernel that compacts twice in a row, as pt_compact_regen_shade does (paths, then shadow rays).
 * The atomics are counted in an instrumented build of the student's file (toolkit/grading/
 * instrument.py): every atomic on a counter also counts itself in the int after the counter. */
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
