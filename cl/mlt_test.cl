/* Test kernel: the Metropolis mutation and acceptance of cl/mlt.h on a known target in
 * primary sample space instead of a light path (host: toolkit/verify/mlt_toy.py, tests/test_mlt.py).
 * The target uses a different number of dimensions in two regions, like paths of different
 * lengths:
 *     u0 <  1/2:  f = 1/2 + u0           uses dimension 0 only (u1 is not read)
 *     u0 >= 1/2:  f = 2 u0 * 3 u1^2       uses dimensions 0 and 1
 * Its integral is 3/8 + 3/4 = 9/8. The dimensions past MLT_MAX_DIMS are never read here. */
#include "mlt.h"

__kernel void mlt_test_target(const MltIteration it, __global const float* proposal, __global float* f,
                              __global int* dims)
{
    int c = get_global_id(0);
    if (c >= it.active) return;
    MltProposal y = {mlt_mutation_sampler(it.seed, c, it.iteration), proposal, (uint)it.chains, (uint)c};
    float u0 = mlt_proposal_dim(&y, 0);
    if (u0 < 0.5f) {
        f[c] = 0.5f + u0;
        dims[c] = 1;
    } else {
        float u1 = mlt_proposal_dim(&y, 1);
        f[c] = 6.0f * u0 * u1 * u1;
        dims[c] = 2;
    }
}

/* The acceptance alone (the renderer does it in mlt_accept_and_weigh, cl/mlt_splat.h): the same
 * mlt_accept_chain of cl/mlt.h. */
__kernel void mlt_accept(const MltIteration it, __global float* current, __global const float* proposal,
                         __global MltChain* chains, __global const float* f_proposal,
                         __global const int* dims_proposal)
{
    int c = get_global_id(0);
    if (c >= it.active) return;
    mlt_accept_chain(it, c, current, proposal, chains, f_proposal, dims_proposal);
}
