/* Kelemen's mutation of primary-sample-space Metropolis (cl/mlt.h, which includes this file):
 * the small step of one uniform (mlt_perturb) and the kernel that writes every chain's proposal
 * (mlt_mutate). It is the file that course assignment 6 (tutorials/assignments/mlt_mutation/)
 * replaces with a student's own.
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
    bool up = r < 0.5f;
    float v = up ? 2.0f * r : 2.0f * r - 1.0f;
    float dv = MLT_S2 * exp(-log(MLT_S2 / MLT_S1) * v);
    float x = up ? u + dv : u - dv;
    x -= floor(x);
    return x < 1.0f ? x : 0.0f;   /* -1e-9 wraps to 1 - 1e-9, which rounds to 1.0f: that is 0 */
}

/* Every chain of the first it.active writes its proposal (a large step in the START and
 * CANDIDATE modes). chains[c].large_step records which step it was. */
__kernel void mlt_mutate(const MltIteration it, __global const float* current, __global float* proposal,
                         __global MltChain* chains)
{
    int c = get_global_id(0);
    if (c >= it.active) return;
    Sampler m = mlt_mutation_sampler(it.seed, c, it.iteration);
    bool large = it.mode != MLT_MUTATE || sampler_get(&m, 0) < it.large_step;
    int used = large ? 0 : chains[c].dims_current;
    for (int d = 0; d < MLT_MAX_DIMS; ++d) {
        size_t i = mlt_index((uint)d, (uint)c, (uint)it.chains);
        proposal[i] = d < used ? mlt_perturb(current[i], mlt_fresh(&m, (uint)d)) : MLT_FRESH;
    }
    chains[c].large_step = large;
}

#endif
