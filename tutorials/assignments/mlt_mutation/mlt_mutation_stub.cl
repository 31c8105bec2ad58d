/* Assignment 6: Kelemen's mutation for primary-sample-space MLT (van Antwerpen, HPG 2011, slide
 * "Metropolis Light Transport": many independent chains, one work-item per chain).
 * Your file replaces the toolkit's cl/mlt_mutation.h (included by cl/mlt.h, which cl/mlt.cl and
 * cl/mlt_test.cl include):
 *     python -m toolkit grade mlt_mutation --kernel THIS_FILE
 * Fill in the two regions marked TODO (mlt_perturb and mlt_mutate); keep the names and the
 * arguments. mlt_accept and mlt_start_from stay the toolkit's, in cl/mlt.h.
 * The rest of this comment is the toolkit's own description of cl/mlt_mutation.h.
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
 * on a GPU a warp runs as long as its longest path, never past MLT_MAX_DIMS. */
#ifndef MLT_MUTATION_H
#define MLT_MUTATION_H

#include "common.h"
#include "philox.h"
#include "mlt_proposals.h"

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

#endif
