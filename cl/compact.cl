/* Stream compaction of alive flags into a stream of indices, two ways (host: toolkit/opencl/compaction.py).
 *
 * Multi-pass (order preserving, stable):
 *   scan_blocks           exclusive scan of each work-group's LOCAL_SIZE values in local memory,
 *                         writing each group's total to block_sums;
 *   (host recursion)      the block sums are scanned the same way, level after level, until
 *                         one group holds them all;
 *   scan_add_block_offsets  adds each group's scanned block sum back to its elements;
 *   compact_scatter       every alive item writes its index to out[offset].
 * Immediate (one pass, the talk's "Immediate Stream Compaction"):
 *   compact_immediate     scan in local memory, one atomic_add per group, direct writes;
 *                         the output is the alive set in unspecified work-group order.
 *
 * Flags are ints: 0 = dead, anything else = alive.
 */
#include "compact.h"

/* Exclusive scan of one work-group's slice of `src` into `dst` (dst may be src: every
 * work-item reads and writes only its own element, and groups own disjoint slices).
 * as_flags != 0 scans (src[i] != 0) instead of src[i]. Work-items past n count as 0 and do
 * not return early: they must reach the barriers inside compact_group_scan. */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void scan_blocks(__global const int* src, const int n, const int as_flags,
                 __global int* dst, __global int* block_sums)
{
    __local int scratch[LOCAL_SIZE];
    int gid = get_global_id(0);
    int value = 0;
    if (gid < n) value = as_flags ? (src[gid] != 0) : src[gid];
    int total;
    int prefix = compact_group_scan(value, scratch, &total);
    if (gid < n) dst[gid] = prefix;
    if (get_local_id(0) == 0) block_sums[get_group_id(0)] = total;
}

/* data[i] += offsets[group of i]: the add-back after the block sums were scanned.
 * No barrier here, so the usual early return is fine. */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void scan_add_block_offsets(__global int* data, const int n, __global const int* block_offsets)
{
    int gid = get_global_id(0);
    if (gid >= n) return;
    data[gid] += block_offsets[get_group_id(0)];
}

/* The scatter pass of multi-pass compaction: offsets is the exclusive scan of the flags. */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void compact_scatter(__global const int* flags, const int n, __global const int* offsets,
                     __global int* out)
{
    int gid = get_global_id(0);
    if (gid >= n) return;
    if (flags[gid] != 0) out[offsets[gid]] = gid;
}

/* Immediate stream compaction of the indices of alive items. counter must be 0 before the
 * launch and holds the count after it. */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void compact_immediate(__global const int* flags, const int n,
                       volatile __global int* counter, __global int* out)
{
    __local int scratch[COMPACT_SCRATCH_INTS];
    int gid = get_global_id(0);
    /* Not `if (gid >= n) return;`: the padding work-items of the last group must still take
     * part in the group's scan and barriers, so they join as dead items. */
    bool alive = gid < n && flags[gid] != 0;
    int slot = immediate_compact_slot(alive, scratch, counter);
    if (slot >= 0) out[slot] = gid;
}
