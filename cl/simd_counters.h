/* The SIMD counters' step log, what every kernel that adds to it shares (host:
 * toolkit/opencl/simd_counters.py): the exact 64-bit add of two 32-bit words, and the sums that
 * a BDPT walk step makes of its own lanes (bdpt_extend, cl/bdpt_walk.h), so that a counted walk
 * step needs no counting launch of its own (cl/simd_counters.cl counts every other step). */
#ifndef SIMD_COUNTERS_H
#define SIMD_COUNTERS_H

#include "common.h"

/* row[field] += x, exactly: a wrapped low word carries into the high one. */
HELPER void add_wide(volatile __global uint* row, int field, uint x) {
    if (x == 0u) return;
    uint old = atomic_add(&row[2 * field], x);
    if (old + x < old) atomic_inc(&row[2 * field + 1]);
}

/* add_wide without a branch: the carry (0 or 1) goes in by a second atomic, even when x is 0. For
 * simd_count_group, which runs after a barrier in a kernel that may have returned early (a
 * work-group past the stream's length): there PoCL 3.0 ran a branch inside the warp's first lane's
 * code wrongly, as if every work-item were its warp's first (tests/test_simd_device.py sees it). */
HELPER void add_wide_unbranched(volatile __global uint* row, int field, uint x) {
    uint old = atomic_add(&row[2 * field], x);
    atomic_add(&row[2 * field + 1], (uint)(old + x < old));
}

/* A walk step's lanes, counted by the work-group that ran them into row `row_index` of the log:
 * what simd_count_warp (cl/simd_counters.cl) adds for the walk's fields, CLOSEST_SUM,
 * CLOSEST_WARP_MAX and SLOT_WARPS (the walk's replay reads only these and LANES, which the step's
 * first work-item writes). `counted`: this work-item's lane is one of the step's (index < length);
 * `closest`: its traversal steps; `slot`: its sample's slot, whose pool warp (slot / warp_width)
 * counts once per step (the warp's stamp, as simd_count_warp's). The warps are the group's
 * consecutive warp_width lanes, as the counting kernel's: warp_width must divide LOCAL_SIZE (the
 * host counts with that kernel otherwise). `lanes`: 2 * LOCAL_SIZE uints of local memory. Every
 * work-item of the group calls it (a barrier); row_index < 0: nothing to count. */
HELPER void simd_count_group(bool counted, uint closest, int slot, volatile __global uint* rows, int row_index,
                             volatile __global int* warp_stamps, int stamp, int warp_width, __local uint* lanes)
{
    const int l = get_local_id(0);
    uint fresh = 0u;
    if (counted && row_index >= 0) fresh = atomic_max(&warp_stamps[slot / warp_width], stamp) < stamp;
    lanes[2 * l] = counted ? closest : 0u;
    lanes[2 * l + 1] = fresh;
    barrier(CLK_LOCAL_MEM_FENCE);
    if ((row_index >= 0) & (l % warp_width == 0)) {   /* a warp's first lane adds up its warp (no branch inside) */
        uint closest_sum = 0u, closest_max = 0u, slot_warps = 0u;
        for (int i = l; i < l + warp_width; ++i) {
            closest_sum += lanes[2 * i];
            closest_max = max(closest_max, lanes[2 * i]);
            slot_warps += lanes[2 * i + 1];
        }
        volatile __global uint* row = rows + row_index * 2 * SIMD_FIELDS;
        add_wide_unbranched(row, SIMD_CLOSEST_SUM, closest_sum);
        add_wide_unbranched(row, SIMD_CLOSEST_WARP_MAX, closest_max);
        add_wide_unbranched(row, SIMD_SLOT_WARPS, slot_warps);
    }
}

#endif
