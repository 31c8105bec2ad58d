/* Stream compaction building blocks (van Antwerpen, HPG 2011, "Immediate Stream Compaction").
 *
 * Reusable device functions for kernels that compact a stream while they run: a path
 * tracing kernel that has just extended its path calls immediate_compact_slot() with
 * alive = "my path continues" and, if it gets a slot >= 0, writes its own record (of
 * whatever struct type) to out[slot]. The standalone kernels are in compact.cl; the host
 * side is toolkit/opencl/compaction.py.
 *
 * Needs -DLOCAL_SIZE=<work-group size> (the host passes the technique's or Compactor's
 * local_size, default program.LOCAL_SIZE = 64): the local scratch is sized at compile time,
 * and every kernel that uses these functions must run with exactly that local size (our
 * kernels say so with reqd_work_group_size; the tests run 32, 64 and 256).
 *
 * RULES FOR CALLERS. These functions contain barriers, so
 *   1. every work-item of the work-group must call them, the same number of times, from
 *      uniform control flow. A kernel must therefore NOT `return` early on `gid >= n`
 *      before calling them: the padding work-items of the last group would skip the
 *      barriers and the group would hang or read garbage (undefined behaviour in OpenCL).
 *      Fold the guard into the flag instead: alive = gid < n && ...;
 *   2. the caller declares the scratch in the kernel (local arrays cannot be declared in
 *      non-kernel functions in OpenCL 1.x):  __local int scratch[COMPACT_SCRATCH_INTS];
 *
 * Like every helper in cl/ they are `static inline` (plain C99 `inline` leaves an undefined
 * symbol on clang-based GPU compilers when a call is not inlined), and, because they contain
 * barriers, also always_inline: PoCL 3.0 runs a kernel that calls a non-inlined static function
 * with barriers into a crash (tests/test_portability.py checks both).
 */
#ifndef COMPACT_H
#define COMPACT_H

#include "common.h"

#ifndef LOCAL_SIZE
#error "compact.h needs -DLOCAL_SIZE=<work-group size> (pass program.LOCAL_SIZE in the defines)"
#endif

/* LOCAL_SIZE ints for the scan, one more to broadcast the group's output base. */
#define COMPACT_SCRATCH_INTS (LOCAL_SIZE + 1)

/* Exclusive prefix sum of `value` over the work-group (Hillis & Steele 1986, in local memory).
 * Returns the sum of `value` over the work-items with a smaller local id, and stores the
 * sum over the whole group in *total (the same in every work-item).
 *
 * Hillis-Steele does log2(LOCAL_SIZE) steps of "add the value `offset` to my left"; it does
 * O(n log n) additions (Blelloch's up/down sweep does O(n)), which is irrelevant at 64 lanes
 * and keeps it to one short loop. It works for any LOCAL_SIZE, not only powers of two.
 * Uses scratch[0 .. LOCAL_SIZE-1]; the trailing barrier lets the caller reuse the scratch
 * (e.g. call again in a loop) right after it returns. */
HELPER int compact_group_scan(int value, __local int* scratch, int* total)
{
    int lid = get_local_id(0);
    scratch[lid] = value;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int offset = 1; offset < LOCAL_SIZE; offset <<= 1) {
        int left = lid >= offset ? scratch[lid - offset] : 0;
        /* Everyone must have read the previous step's values before anyone overwrites its
         * own slot; without this barrier a work-item could add a neighbour's value that
         * already includes this step (a data race, wrong on GPUs and on PoCL alike). */
        barrier(CLK_LOCAL_MEM_FENCE);
        scratch[lid] += left;
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    int inclusive = scratch[lid];
    *total = scratch[LOCAL_SIZE - 1];
    barrier(CLK_LOCAL_MEM_FENCE); /* all reads done before the scratch is reused */
    return inclusive - value;
}

/* Immediate stream compaction of one work-group, in a single pass:
 *   1. label: each work-item says whether its item survives (`alive`);
 *   2. scan:  a parallel scan of the labels in local memory gives each survivor its rank
 *             among the group's survivors;
 *   3. allocate: ONE atomic_add per work-group (by local id 0) on the global `counter`
 *             reserves a contiguous range for the group's survivors in the output stream;
 *   4. write: the caller writes its own record to out[slot].
 * Returns the output slot of this work-item, or -1 if it is not alive. Slots within a
 * work-group follow local-id order; the order of the work-groups' ranges is whatever order
 * their atomics happened in, so the output is the alive set in UNSPECIFIED BLOCK ORDER.
 * `counter` must be zero before the launch; afterwards it holds the number of survivors.
 * 32-bit atomic_add on a __global int is OpenCL 1.1 core (no extension needed).
 * Uses all COMPACT_SCRATCH_INTS ints of scratch; see the rules at the top of this file. */
HELPER int immediate_compact_slot(bool alive, __local int* scratch, volatile __global int* counter)
{
    int total;
    int rank = compact_group_scan(alive ? 1 : 0, scratch, &total);
    if (get_local_id(0) == 0)
        scratch[LOCAL_SIZE] = total > 0 ? atomic_add(counter, total) : 0; /* dead groups skip the atomic */
    barrier(CLK_LOCAL_MEM_FENCE);
    int base = scratch[LOCAL_SIZE];
    barrier(CLK_LOCAL_MEM_FENCE); /* everyone has the base before a next call overwrites it */
    return alive ? base + rank : -1;
}

#endif
