/* Assignment 6: Kelemen's mutation for primary-sample-space MLT (van Antwerpen, HPG 2011, slide
 * "Metropolis Light Transport": many independent chains, one work-item per chain).
 * Your file replaces the toolkit's cl/mlt.h (included by cl/mlt.cl and cl/mlt_test.cl):
 *     python -m toolkit grade mlt_mutation --kernel THIS_FILE
 * Fill in the two regions marked TODO (mlt_perturb and mlt_mutate); keep the names and the
 * arguments. mlt_accept and mlt_start_from are given, as the toolkit has them.
 * The rest of this comment is the toolkit's own description of cl/mlt.h.
 *
 * Primary-sample-space Metropolis (Kelemen, Szirmay-Kalos, Antal, Csonka 2002, "A Simple and
 * Robust Mutation Strategy for the Metropolis Light Transport Algorithm"), as the talk's slide
 * "Metropolis Light Transport" runs it: many independent chains, one work-item per chain.
 *
 * A chain's state is a vector of uniforms u in [0, 1)^MLT_MAX_DIMS (the dimensions of the BDPT
 * table, toolkit/core/sample_dims.py), stored at primary[mlt_index(dim, chain, chains)]
 * (cl/mlt_proposals.h: dimension-major on a GPU, chain-major on a CPU). Only the first `dims` of them were used by the state's path (its
 * prefix, from the vertex counts: toolkit/techniques/mlt.py); the rest are unused, uniform noise.
 *
 * One iteration: mlt_mutate writes every chain's proposal, the BDPT kernels evaluate it
 * (cl/bdpt_sampler.h answers their uniforms from the proposal), the host sums each proposal's
 * contribution f (luminance of all its strategies), mlt_accept keeps or rejects it.
 *
 * The mutation (Kelemen sec. 4, the talk's variation "only mutate sample dimensions used in
 * both current and mutated sample"):
 *   large step (probability large_step): every dimension drawn afresh, a BDPT sample;
 *   small step: a dimension the current state used is perturbed by Kelemen's exponential
 *     kernel, u' = u +- s2 exp(-log(s2 / s1) v) wrapped to [0, 1) (s2 = the option small_step,
 *     1/16 by default, and s1 = s2 / 16: MLT_S2 and MLT_S1, set by the host);
 *     a dimension it did not use is drawn afresh. Of the proposal's dimensions, the ones it
 *     uses and the current state used are thus perturbed, the others fresh.
 * Why the proposal is symmetric, T(x -> y) = T(y -> x), as Metropolis-Hastings with
 * a = min(1, f(y) / f(x)) needs: a state is the values of the dimensions it uses (f depends on
 * nothing else). The density of proposing y's used values from x is the product, over the
 * dimensions both use, of the perturbation density k(x_d, y_d), times 1 (uniform) for the
 * dimensions only y uses; the dimensions only x uses do not appear (y ignores them). From y
 * back to x the same dimensions are perturbed (both use them) with k(y_d, x_d) = k(x_d, y_d)
 * (the kernel depends on |y_d - x_d| around the circle only), and x's extra dimensions come
 * fresh with density 1. Same product both ways. A large step is an independent uniform
 * proposal, symmetric as well; the mixture of the two is symmetric. Dimensions past
 * MLT_MAX_DIMS are fresh at every iteration (cl/mlt_proposals.h): the same "fresh, density 1" case.
 *
 * Random numbers of the mutation itself come from Philox, keyed by (chain, iteration) under
 * MLT_MUTATION_KEY (cl/mlt_proposals.h): dimension 0 chooses the step, 1 decides the acceptance, 2 + d
 * perturbs dimension d or is its fresh value. A fresh value is not written by mlt_mutate (the
 * proposal holds the mark MLT_FRESH) but drawn where the BDPT kernels read it (cl/mlt_proposals.h,
 * mlt_proposal_dim), and mlt_accept stores it for the dimensions the accepted path used: so a
 * mutation costs random numbers and copies for the dimensions its paths use, not for all
 * MLT_MAX_DIMS. mlt_mutate still writes every stored word (a perturbed value or the mark), a
 * cheap even store; the perturbations and mlt_accept's copy run to each chain's own count, so
 * on a GPU a warp runs as long as its longest path, never past MLT_MAX_DIMS.
 * Host: toolkit/techniques/mlt.py; test kernel: cl/mlt_test.cl. */
#ifndef MLT_H
#define MLT_H

#include "common.h"
#include "philox.h"
#include "mlt_proposals.h"

#if !defined(MLT_S1) || !defined(MLT_S2)
#error "MLT_S1 and MLT_S2 (the small step's sizes) come from the host: toolkit/techniques/mlt.py step_defines"
#endif

/* Kelemen's small step of one uniform u, driven by one uniform r: the sign from r < 1/2, the
 * size s2 exp(-log(s2 / s1) v) with v uniform in [0, 1) (sizes from s1 to s2, denser
 * towards the small ones), wrapped around [0, 1). Symmetric: +dv and -dv equally likely. */
HELPER float mlt_perturb(float u, float r) {
    /* TODO: the sign from r < 1/2, v from r (uniform in [0, 1) on either side), the size
     * s2 exp(-log(s2 / s1) v), and the result wrapped into [0, 1). */
    (void)r;
    return u;
}

/* Every chain of the first it.active writes its proposal (a large step in the START and
 * CANDIDATE modes). chains[c].large_step records which step it was. */
__kernel void mlt_mutate(const MltIteration it, __global const float* current, __global float* proposal,
                         __global MltChain* chains)
{
    /* TODO: the mutation's random numbers (mlt_mutation_sampler): dimension 0 chooses the step
     * (large with probability it.large_step in MLT_MUTATE, always in the other modes); write
     * every stored dimension of the proposal (mlt_index): perturbed from the current state for
     * the dimensions it used (a small step), the mark MLT_FRESH for the others; record the step. */
    (void)it; (void)current; (void)proposal; (void)chains;
}

/* Metropolis-Hastings acceptance of the proposals whose contributions f (luminance over all
 * strategies) and used dimensions the host has summed: a = min(1, f(y) / f(x)), and a = 1 from
 * a state with f = 0 (the start may have one). START: always accepted. CANDIDATE (start =
 * resample): weighted reservoir sampling, kept with probability f / (sum of f so far), so after
 * N candidates the state is candidate i with probability f_i / sum f. The accepted vector is
 * copied into the chain's current one (its used dimensions); `acceptance` is what the host weights the splats with. */
__kernel void mlt_accept(const MltIteration it, __global float* current, __global const float* proposal,
                         __global MltChain* chains, __global const float* f_proposal,
                         __global const int* dims_proposal)
{
    int c = get_global_id(0);
    if (c >= it.active) return;
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
        a = chain.f_current > 0.0f ? fmin(1.0f, fy / chain.f_current) : 1.0f;
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
    chains[c] = chain;
}

/* start = pool: chain c starts at a large step that chain src_chain[c] evaluated in iteration
 * src_iteration[c] (the host picked it from all chains' candidates in proportion to f). A large
 * step's dimensions were all fresh, so its vector is the mutation's random numbers of that
 * (chain, iteration), drawn again here for the dimensions its path used. */
__kernel void mlt_start_from(const MltIteration it, __global float* current, __global MltChain* chains,
                             __global const int* src_chain, __global const int* src_iteration,
                             __global const float* f, __global const int* dims)
{
    int c = get_global_id(0);
    if (c >= it.active) return;
    Sampler m = mlt_mutation_sampler(it.seed, src_chain[c], src_iteration[c]);
    int used = min(dims[c], MLT_MAX_DIMS);
    for (int d = 0; d < used; ++d)
        current[mlt_index((uint)d, (uint)c, (uint)it.chains)] = mlt_fresh(&m, (uint)d);
    chains[c].f_current = f[c];
    chains[c].dims_current = dims[c];
}

#endif
