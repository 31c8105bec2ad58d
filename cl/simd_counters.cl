/* The SIMD counters summed on the device (host: toolkit/opencl/simd_counters.py).
 *
 * A counting step's kernels write one LaneCounts per lane (what the lane did: layout.h). Reading
 * them back after every step drained the device's queue each time and left the host summing
 * hundreds of thousands of lanes in numpy. Here each step's lanes are added up into one row of a
 * step log (SimdSum, layout.h): lanes with work, warps with work, each warp's longest loop, ...,
 * exactly the integers the talk's model needs (toolkit/core/simd.py), and the host reads the log
 * once per pass or per frame.
 *
 * Exact in any order: every sum is an integer, kept as two 32-bit words (low, high) that 32-bit
 * atomics add to (OpenCL 1.1's core, every device): a low word that wraps carries one into the
 * high word. Integers added in another order are the same integers, so the row is what the
 * host's sums were, bit for bit. */
#include "simd_counters.h"

/* One work-item per warp, its sums into row `row_index` of the log: the warp's `warp_width`
 * consecutive lanes of the first n, where n is `bound` or, when length_index >= 0,
 * length_at[length_index] (a count the device holds: the step's stream length), whichever is
 * smaller (`step`'s fields: SimdStep, layout.h). Lane i's ints are lanes[i * stride ..]: the
 * LaneCounts fields in order (work, closest_steps, shadow_rays, shadow_steps; stride 4), or one
 * int (stride 1: work only).
 * Optional, each off when its int argument is negative or zero:
 *   watch_count: work-item 0 copies that many ints of `watch` into the row (the step's counts);
 *   histogram_row: lanes and warps counted by work (and by warp's largest work) into column
 *     histogram_row of `histogram` ([bin][lanes, warps][histogram_rows]; bins - 1 >= any work);
 *   stamp (an argument): lane i's sample slot is slot_of[slot_offset + i]; a pool warp (slot / warp_width) not yet
 *     stamped with `stamp` gets it and counts once in SLOT_WARPS (warp_stamps only grow);
 *   aux_bound: a second buffer of one int per lane (a step's other kernel: pt_inplace_regen's
 *     regeneration), its first aux_bound summed into the AUX_ fields. */
HELPER void simd_count_warp(int warp, __global const int* lanes, __global const int* length_at,
                            volatile __global uint* rows, int row_index, __global const int* watch,
                            volatile __global uint* histogram, __global const int* slot_of,
                            volatile __global int* warp_stamps, int stamp, __global const int* aux,
                            const SimdStep step)
{
    int stride = step.stride, warp_width = step.warp_width;
    int bins = step.bins, histogram_row = step.histogram_row, histogram_rows = step.histogram_rows;
    int slot_offset = step.slot_offset;
    volatile __global uint* row = rows + row_index * 2 * SIMD_FIELDS;
    int n = step.length_index >= 0 ? min(step.bound, length_at[step.length_index]) : step.bound;
    int n_aux = step.aux_bound;
    if (warp == 0) {
        row[2 * SIMD_LANES] = (uint)max(n, 0);
        row[2 * SIMD_AUX_COUNT] = (uint)max(n_aux, 0);
        for (int k = 0; k < step.watch_count; ++k) row[2 * (SIMD_WATCH + k)] = (uint)watch[k];
    }
    if (warp * warp_width < n_aux) {   /* the second buffer: one int per lane */
        uint lanes_on = 0, sum = 0, longest = 0;
        for (int i = warp * warp_width; i < min((warp + 1) * warp_width, n_aux); ++i) {
            uint value = (uint)aux[i];
            lanes_on += value > 0u;
            sum += value;
            longest = max(longest, value);
        }
        add_wide(row, SIMD_AUX_LANES, lanes_on);
        add_wide(row, SIMD_AUX_WARPS, lanes_on > 0u);
        add_wide(row, SIMD_AUX_SUM, sum);
        add_wide(row, SIMD_AUX_WARP_MAX, longest);
    }
    int first = warp * warp_width;
    if (first >= n) return;
    uint work_lanes = 0, work_sum = 0, work_max = 0, closest_sum = 0, closest_max = 0;
    uint shadow_lanes = 0, shadow_sum = 0, steps_sum = 0, steps_max = 0, slot_warps = 0;
    for (int i = first; i < min(first + warp_width, n); ++i) {
        __global const int* lane = lanes + (long)i * stride;
        uint work = (uint)lane[0];
        work_lanes += work > 0u;
        work_sum += work;
        work_max = max(work_max, work);
        if (stride > 1) {
            uint closest = (uint)lane[1], shadow = (uint)lane[2], steps = (uint)lane[3];
            closest_sum += closest;
            closest_max = max(closest_max, closest);
            shadow_lanes += shadow > 0u;
            shadow_sum += shadow;
            steps_sum += steps;
            steps_max = max(steps_max, steps);
        }
        if (histogram_row >= 0)
            atomic_inc(&histogram[(min((int)work, bins - 1) * 2) * histogram_rows + histogram_row]);
        if (stamp > 0) {
            int slot_warp = slot_of[slot_offset + i] / warp_width;
            slot_warps += atomic_max(&warp_stamps[slot_warp], stamp) < stamp;
        }
    }
    if (histogram_row >= 0)
        atomic_inc(&histogram[(min((int)work_max, bins - 1) * 2 + 1) * histogram_rows + histogram_row]);
    add_wide(row, SIMD_WORK_LANES, work_lanes);
    add_wide(row, SIMD_WORK_WARPS, work_lanes > 0u);
    add_wide(row, SIMD_WORK_SUM, work_sum);
    add_wide(row, SIMD_WORK_WARP_MAX, work_max);
    if (work_max > 0u) atomic_max(&row[2 * SIMD_WORK_MAX], work_max);
    add_wide(row, SIMD_CLOSEST_SUM, closest_sum);
    add_wide(row, SIMD_CLOSEST_WARP_MAX, closest_max);
    add_wide(row, SIMD_SHADOW_LANES, shadow_lanes);
    add_wide(row, SIMD_SHADOW_WARPS, shadow_lanes > 0u);
    add_wide(row, SIMD_SHADOW_SUM, shadow_sum);
    add_wide(row, SIMD_SHADOW_STEPS_SUM, steps_sum);
    add_wide(row, SIMD_SHADOW_STEPS_WARP_MAX, steps_max);
    add_wide(row, SIMD_SLOT_WARPS, slot_warps);
}

__kernel void simd_count_lanes(__global const int* lanes, __global const int* length_at,
                               volatile __global uint* rows, __global const int* watch,
                               volatile __global uint* histogram, __global const int* slot_of,
                               volatile __global int* warp_stamps, __global const int* aux, const SimdStep step,
                               const int row, const int stamp)
{
    simd_count_warp(get_global_id(0), lanes, length_at, rows, row, watch, histogram, slot_of, warp_stamps, stamp, aux,
                    step);
}

/* Two steps in one launch, each what simd_count_lanes counts but a histogram: warps below `warps`
 * count `step` over its buffers into `row` (stamp `stamp`), the others `step_b` over theirs into
 * row + 1 (stamp_b), each from its own warp 0. The
 * BDPT walk's eye and light streams, and a path tracer's two consecutive steps (whose lanes the
 * step kernels wrote to two buffers in turn): a launch is most of a counted step's host time.
 * Each step has its own stamps (warp_stamps_b): the two run at once, and a stamp must find the
 * warps it has not seen. */
__kernel void simd_count_two_steps(__global const int* lanes, __global const int* length_at,
                                   __global const int* watch, __global const int* slot_of,
                                   volatile __global int* warp_stamps, __global const int* aux,
                                   __global const int* lanes_b, __global const int* length_at_b,
                                   __global const int* watch_b, __global const int* slot_of_b,
                                   volatile __global int* warp_stamps_b, __global const int* aux_b,
                                   volatile __global uint* rows, const int row, const int stamp,
                                   const int stamp_b, const int warps, const SimdStep step, const SimdStep step_b)
{
    int warp = get_global_id(0);
    if (warp < warps)
        simd_count_warp(warp, lanes, length_at, rows, row, watch, 0, slot_of, warp_stamps, stamp, aux, step);
    else
        simd_count_warp(warp - warps, lanes_b, length_at_b, rows, row + 1, watch_b, 0, slot_of_b, warp_stamps_b,
                        stamp_b, aux_b, step_b);
}

/* `steps` consecutive steps in one launch, each what simd_count_lanes counts over `bound` lanes
 * (no device length, watch, histogram or slots: `step`, one record for all): a path tracer's step
 * kernels write step t of a round to turn t of buffers that hold a round's steps, `turn_lanes`
 * lanes apart (pt_inplace_regen). Step s of the launch is turn first_turn + s, its sums go to
 * row + s; warps [s * warps, (s + 1) * warps) count it. A launch counts a whole round, so a step
 * costs the host an eighth of a launch, not half of one. */
__kernel void simd_count_turns(__global const int* lanes, __global const int* aux, volatile __global uint* rows,
                               const int row, const int first_turn, const int steps, const int warps,
                               const int turn_lanes, const SimdStep step)
{
    int gid = get_global_id(0), s = gid / warps;
    if (s >= steps) return;      /* the launch's padding: no step's warp */
    long turn = first_turn + s;
    simd_count_warp(gid - s * warps, lanes + turn * turn_lanes * step.stride, 0, rows, row + s, 0, 0, 0, 0, 0,
                    aux + turn * turn_lanes, step);
}

/* The same loops with only the lanes that have work, packed side by side in lane order (the naive
 * connect phase as if only the terminated samples ran): PACKED_WARP_MAX += each packed warp's
 * largest work. One work-group walks the first n lanes in order, LOCAL_SIZE at a time: a scan of
 * "has work" in local memory gives each such lane its packed index, the packed warps a chunk
 * touches take their largest work, and those it completes are added; the last one, still
 * filling, carries into the next chunk. A pass of a connect phase, in the counters' own time. */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void simd_count_packed(__global const int* lanes, const int stride, const int n, const int warp_width,
                       volatile __global uint* rows, const int row_index)
{
    volatile __global uint* row = rows + row_index * 2 * SIMD_FIELDS;
    __local int rank[LOCAL_SIZE];
    __local uint warp_max[LOCAL_SIZE + 2];   /* the packed warps one chunk touches (warp_width >= 1) */
    __local uint open_max;                   /* the largest work of the packed warp still filling */
    int l = get_local_id(0), packed = 0;     /* packed: lanes with work before this chunk (the same in every work-item) */
    if (l == 0) open_max = 0u;
    for (int first = 0; first < n; first += LOCAL_SIZE) {
        int i = first + l;
        uint work = i < n ? (uint)lanes[(long)i * stride] : 0u;
        rank[l] = work > 0u;
        barrier(CLK_LOCAL_MEM_FENCE);
        for (int offset = 1; offset < LOCAL_SIZE; offset *= 2) {   /* inclusive scan (Hillis and Steele) */
            int before = l >= offset ? rank[l - offset] : 0;
            barrier(CLK_LOCAL_MEM_FENCE);
            rank[l] += before;
            barrier(CLK_LOCAL_MEM_FENCE);
        }
        int count = rank[LOCAL_SIZE - 1], first_warp = packed / warp_width;
        for (int k = l; k < LOCAL_SIZE + 2; k += LOCAL_SIZE) warp_max[k] = 0u;
        barrier(CLK_LOCAL_MEM_FENCE);
        if (l == 0) warp_max[0] = open_max;
        barrier(CLK_LOCAL_MEM_FENCE);
        if (work > 0u) atomic_max(&warp_max[(packed + rank[l] - 1) / warp_width - first_warp], work);
        barrier(CLK_LOCAL_MEM_FENCE);
        packed += count;
        int completed = packed / warp_width - first_warp;
        if (l == 0) {
            for (int k = 0; k < completed; ++k) add_wide(row, SIMD_PACKED_WARP_MAX, warp_max[k]);
            open_max = warp_max[completed];
        }
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    if (l == 0) add_wide(row, SIMD_PACKED_WARP_MAX, open_max);   /* the last warp, if partly filled */
}
