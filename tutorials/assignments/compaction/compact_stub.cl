/* Assignment 2: immediate stream compaction (van Antwerpen, HPG 2011, slide "Immediate Stream
 * Compaction"). Your file replaces the toolkit's cl/compact.h: grade it with
 *     python -m toolkit grade compaction --kernel THIS_FILE
 * The toolkit's kernels (cl/compact.cl, cl/pt_compact_regen.cl) call the two functions below;
 * keep their names and signatures. Fill in the regions marked TODO.
 *
 * RULES FOR CALLERS (the kernels that call you keep them; your code may rely on them):
 *   - every work-item of the work-group calls these functions, the same number of times,
 *     from uniform control flow (so barriers inside them are allowed and needed);
 *   - the caller declares  __local int scratch[COMPACT_SCRATCH_INTS];  and passes it in;
 *   - the work-group size is exactly LOCAL_SIZE (a -D define from the host, 64). */
#ifndef COMPACT_H
#define COMPACT_H

#ifndef LOCAL_SIZE
#error "compact.h needs -DLOCAL_SIZE=<work-group size> (pass program.LOCAL_SIZE in the defines)"
#endif

/* LOCAL_SIZE ints for the scan, one more to broadcast the group's output base. */
#define COMPACT_SCRATCH_INTS (LOCAL_SIZE + 1)

/* Exclusive prefix sum of `value` over the work-group, in local memory.
 * Returns the sum of `value` over the work-items with a smaller local id, and stores the sum
 * over the whole group in *total (the same in every work-item). Use scratch[0 .. LOCAL_SIZE-1].
 * The caller may call it again right after it returns (with the same scratch). */
static inline __attribute__((always_inline)) int compact_group_scan(int value, __local int* scratch, int* total)
{
    int lid = get_local_id(0);
    /* TODO: store value in scratch[lid]; scan scratch in log2(LOCAL_SIZE) steps (Hillis &
     * Steele: add the value `offset` to your left, offset = 1, 2, 4, ...); read the inclusive
     * sum and the group total; return the exclusive sum. Put a barrier wherever one
     * work-item reads what another one writes. */
    (void)lid;
    (void)value;
    (void)scratch;
    *total = 0;
    return 0;
}

/* Immediate stream compaction of one work-group, in a single pass:
 *   1. label: each work-item says whether its item survives (`alive`);
 *   2. scan:  the exclusive scan of the labels gives each survivor its rank in the group;
 *   3. allocate: ONE atomic_add per work-group on the global `counter` reserves a range
 *      for the group's survivors in the output stream;
 *   4. write: the caller writes its own record to out[slot].
 * Returns the output slot of this work-item, or -1 if it is not alive. `counter` is zero
 * before the launch and holds the number of survivors after it. Use scratch[LOCAL_SIZE] to
 * share the group's base with the other work-items. */
static inline __attribute__((always_inline)) int immediate_compact_slot(bool alive, __local int* scratch, volatile __global int* counter)
{
    /* TODO: scan the labels with compact_group_scan; local id 0 does the group's atomic_add
     * and stores the base in scratch[LOCAL_SIZE]; every work-item reads it (barriers!) and
     * returns base + rank if alive. */
    (void)alive;
    (void)scratch;
    (void)counter;
    return -1;
}

#endif
