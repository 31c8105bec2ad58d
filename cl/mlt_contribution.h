/* Each proposal's contribution f and used dimensions, summed on the device from the records of
 * a connect phase (cl/bdpt_parallel_connect.cl), and its records copied to the proposal store
 * (cl/mlt_splat.h), where the splats find them: the host reads no record.
 *
 * One work-item per pool slot. The parallel connect phase writes a slot's records consecutively,
 * from firsts[slot] (the scan of counts), so the work-item adds its sample's records one after
 * another, in the order they were written: the same records give the same f bits on every run
 * (no atomics on floats). A slot holds one proposal (its sample id is its chain) and is connected
 * once per iteration, so each chain's f and dims are written by one work-item.
 *
 * f is the luminance of the sum of all strategies (toolkit/techniques/mlt.py); a record without
 * a pixel (-1) adds nothing, a non-finite one is dropped and counted in tallies[MLT_TALLY_NONFINITE]
 * (a bug to report, never a NaN in a chain), and a proposal that read more than MLT_MAX_DIMS
 * dimensions is counted in tallies[MLT_TALLY_OVERFLOW] (still correct: cl/mlt_proposals.h).
 * Integer atomics: the tallies are the same in any order. */
#ifndef MLT_CONTRIBUTION_H
#define MLT_CONTRIBUTION_H

__kernel void mlt_proposal_sums(const int pool, __global const BdptSlot* slots, __global const int* counts,
                                __global const int* firsts, __global const float4* record_value,
                                __global const int* record_pixel, __global float* f_proposal,
                                __global int* dims_proposal, __global int* tallies, const int store_base,
                                __global float4* store_value, __global int* store_pixel, __global int* store_chain,
                                __global int2* proposal_span)
{
    int slot = get_global_id(0);
    if (slot >= pool) return;
    int n = counts[slot];
    if (n == 0) return;                  /* nothing connected in this slot during this phase */
    BdptSlot sample = slots[slot];
    float f = 0.0f;
    int nonfinite = 0;
    int to = store_base + firsts[slot];     /* this phase's records follow the iteration's earlier phases' */
    for (int k = firsts[slot]; k < firsts[slot] + n; ++k, ++to) {
        float3 value = record_value[k].xyz;
        int pixel = record_pixel[k];
        if (pixel >= 0 && !all_finite(value)) { ++nonfinite; pixel = -1; }
        if (pixel >= 0) f += luminance(value);
        store_value[to] = (float4)(value, 0.0f);  /* .w: the splat weight, set before each splat */
        store_pixel[to] = pixel;                  /* -1: splats nothing */
        store_chain[to] = sample.sample_id;
    }
    proposal_span[sample.sample_id] = (int2)(store_base + firsts[slot], n);   /* first record, count */
    int dims = used_dims(sample.eye_vertices, sample.light_vertices);
    f_proposal[sample.sample_id] = fmax(f, 0.0f);
    dims_proposal[sample.sample_id] = min(dims, MLT_MAX_DIMS);
    if (nonfinite) atomic_add(&tallies[MLT_TALLY_NONFINITE], nonfinite);
    if (dims > MLT_MAX_DIMS) atomic_inc(&tallies[MLT_TALLY_OVERFLOW]);
}

#endif
