/* Primary-sample-space Metropolis (Kelemen, Szirmay-Kalos, Antal, Csonka 2002, "A Simple and
 * Robust Mutation Strategy for the Metropolis Light Transport Algorithm"), as the talk's slide
 * "Metropolis Light Transport" runs it: many independent chains, one work-item per chain.
 *
 * A chain's state is a vector of uniforms u in [0, 1)^MLT_MAX_DIMS (the dimensions of the BDPT
 * table, toolkit/core/sample_dims.py), stored at primary[mlt_index(dim, chain, chains)]
 * (cl/mlt_proposals.h: dimension-major on a GPU, chain-major on a CPU). Only the first `dims` of them were used by the state's path (its
 * prefix, from the vertex counts: toolkit/techniques/mlt.py); the rest are unused, uniform noise.
 *
 * One iteration: mlt_mutate writes every chain's proposal, the BDPT kernels evaluate it
 * (cl/bdpt_sampler.h answers their uniforms from the proposal), mlt_proposal_sums sums each proposal's
 * contribution f (luminance of all its strategies, cl/mlt_contribution.h), mlt_accept keeps or rejects it.
 *
 * The mutation, its random numbers and why its proposal is symmetric: cl/mlt_mutation.h (the
 * file that course assignment 6, tutorials/assignments/mlt_mutation/, replaces with a student's own).
 * Host: toolkit/techniques/mlt.py; test kernel: cl/mlt_test.cl. */
#ifndef MLT_H
#define MLT_H

#include "common.h"
#include "philox.h"
#include "mlt_proposals.h"

#if !defined(MLT_S1) || !defined(MLT_S2)
#error "MLT_S1 and MLT_S2 (the small step's sizes) come from the host: toolkit/techniques/mlt.py step_defines"
#endif

/* mlt_perturb and the mlt_mutate kernel */
#include "mlt_mutation.h"

/* a = min(1, f(y) / f(x)), and 1 from a state with f = 0: the one formula of mlt_accept and of
 * the splat weights (cl/mlt_splat.h), so both see the same a. */
HELPER float mlt_acceptance(float f_current, float f_proposal) {
    return f_current > 0.0f ? fmin(1.0f, f_proposal / f_current) : 1.0f;
}

/* Metropolis-Hastings acceptance of the proposals whose contributions f (luminance over all
 * strategies) and used dimensions mlt_proposal_sums has summed: a = min(1, f(y) / f(x)), and a = 1 from
 * a state with f = 0 (the start may have one). START: always accepted. CANDIDATE (start =
 * resample): weighted reservoir sampling, kept with probability f / (sum of f so far), so after
 * N candidates the state is candidate i with probability f_i / sum f. The accepted vector is
 * copied into the chain's current one (its used dimensions). The splats' weights use the same a
 * (mlt_acceptance), computed before it by mlt_chain_splat_weights (cl/mlt_splat.h).
 * One chain's acceptance: the body of the kernel mlt_accept (cl/mlt_test.cl, the toy target's)
 * and of mlt_accept_and_weigh (cl/mlt_splat.h: the render's, weights and acceptance in one launch). */
HELPER void mlt_accept_chain(const MltIteration it, int c, __global float* current, __global const float* proposal,
                             __global MltChain* chains, __global const float* f_proposal,
                             __global const int* dims_proposal)
{
    Sampler m = mlt_mutation_sampler(it.seed, c, it.iteration);
    MltChain chain = chains[c];
    float fy = f_proposal[c];
    float a;
    if (it.mode == MLT_START) {
        a = 1.0f;
    } else if (it.mode == MLT_CANDIDATE) {
        chain.candidates += fy;
        a = chain.candidates > 0.0f ? fy / chain.candidates : 1.0f;   /* all zero so far: any will do */
    } else {
        a = mlt_acceptance(chain.f_current, fy);
    }
    bool accept = sampler_get(&m, 1) < a;
    if (accept) {   /* the dimensions the new state used: perturbed ones as stored, fresh ones drawn */
        MltProposal y = {m, proposal, (uint)it.chains, (uint)c};
        int used = min(dims_proposal[c], MLT_MAX_DIMS);
        for (int d = 0; d < used; ++d)
            current[mlt_index((uint)d, (uint)c, (uint)it.chains)] = mlt_proposal_dim(&y, (uint)d);
        chain.f_current = fy;
        chain.dims_current = dims_proposal[c];
    }
    chain.accepted = accept;
    chain.acceptance = a;
    chain.f_proposal = fy;            /* the proposal as this acceptance saw it */
    chain.dims_proposal = dims_proposal[c];
    chains[c] = chain;
}

#endif
