/* start = pool on the device (host: toolkit/techniques/mlt.py evaluate_candidates and
 * start_from_pool). The chains' candidates were evaluated as one batch of BDPT samples (cl/bdpt_walk.h
 * bdpt_sampler_mlt: candidate k is chain k % chains's large step of iteration first + k / chains),
 * whose f, dimensions and records mlt_proposal_sums kept per candidate (cl/mlt_contribution.h).
 * Every candidate is a large step, so its f goes into b (mlt_candidates_into_b, then
 * mlt_estimate_first_b); each chain starts at the candidate the host picked for it
 * (mlt_start_from), without evaluating it again. */
#ifndef MLT_START_H
#define MLT_START_H

#include "common.h"
#include "mlt.h"
#include "mlt_splat.h"

/* Every candidate's f into b's sum, and its count into the large steps' (cl/mlt_splat.h mlt_add_to_b). */
__kernel void mlt_candidates_into_b(const int candidates, const int unit_exponent, __global const float* f_candidate,
                                    __global FilmAccumulator* b_sum, __global int* tallies)
{
    int k = get_global_id(0);
    if (k >= candidates) return;
    mlt_add_to_b(f_candidate[k], unit_exponent, b_sum, tallies);
}

/* b for the first iteration's weights, once every candidate is in b's sum (one work-item). */
__kernel void mlt_estimate_first_b(__global FilmAccumulator* b_sum, const int unit_exponent,
                                   __global const int* tallies, __global float* b_estimate)
{
    if (get_global_id(0) == 0) mlt_estimate_b(b_sum, unit_exponent, tallies, b_estimate);
}

/* Chain c starts at candidate pick[c] (the host picked them from all the chains' candidates in
 * proportion to f; it.iteration: the batch's first). A large step's dimensions were all fresh,
 * so its vector is the mutation's random numbers of its (chain, iteration), drawn again here for
 * the dimensions its path used; its f, dimensions and records become the chain's current
 * state's, accepted. The records go to the current store as mlt_keep_records puts them
 * (it.store_capacity: the host counted them exactly). */
__kernel void mlt_start_from(const MltIteration it, __global const int* pick, __global const float* f_candidate,
                             __global const int* dims_candidate, __global const int2* candidate_span,
                             __global const float4* candidate_value, __global const int* candidate_pixel,
                             __global float* current, __global MltChain* chains, __global int2* next_span,
                             __global float4* next_value, __global int* next_pixel, __global int* next_chain,
                             __global int* next_total, __global int* tallies)
{
    int c = get_global_id(0);
    if (c >= it.active) return;
    int k = pick[c];
    Sampler m = mlt_mutation_sampler(it.seed, k % it.chains, it.iteration + k / it.chains);
    int used = min(dims_candidate[k], MLT_MAX_DIMS);
    for (int d = 0; d < used; ++d)
        current[mlt_index((uint)d, (uint)c, (uint)it.chains)] = mlt_fresh(&m, (uint)d);
    MltChain chain = chains[c];
    chain.f_current = chain.f_proposal = f_candidate[k];
    chain.dims_current = chain.dims_proposal = dims_candidate[k];
    chain.accepted = 1;
    chain.acceptance = 1.0f;
    chains[c] = chain;
    mlt_store_records(c, candidate_span[k], candidate_value, candidate_pixel, it.store_capacity, next_span,
                      next_value, next_pixel, next_chain, next_total, tallies);
}

#endif
