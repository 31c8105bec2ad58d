/* Metropolis proposals (cl/mlt.h): where a chain's primary-sample vector is stored, and how the
 * BDPT code reads a proposal's uniforms from it. The uniforms of chain `chain`'s proposal are
 * stored at primary[mlt_index(dim, chain, chains)] (below). A dimension the mutation perturbed
 * holds its value there; a dimension the mutation draws afresh holds the mark MLT_FRESH (< 0),
 * and its value is the mutation's own random number for it, Philox (seed ^ MLT_MUTATION_KEY,
 * chain, iteration), dimension 2 + dim, drawn where it is read. So a large step costs the random
 * numbers its path reads, not MLT_MAX_DIMS of them. Dimensions >= MLT_MAX_DIMS are not stored:
 * always fresh, at every iteration, an independent proposal, which is symmetric too, so the
 * chain stays correct; it only explores such long paths like a large step would (cl/mlt.h). */
#ifndef MLT_PROPOSALS_H
#define MLT_PROPOSALS_H

#include "common.h"
#include "philox.h"

#ifndef MLT_MAX_DIMS
#error "MLT_MAX_DIMS (stored dimensions per chain) comes from the host: toolkit/techniques/mlt.py (option max_dims)"
#endif
#define MLT_MUTATION_KEY 0x6d757461u
#define MLT_FRESH (-1.0f)

/* Where dimension `dim` of chain `chain` is stored. Dimension-major (dim * chains + chain): the
 * work-items of a warp, chains c .. c + 31 in mlt_mutate and mlt_accept, touch neighbouring
 * words (coalesced on a GPU). Chain-major (MLT_CHAIN_MAJOR, chosen by the host on a CPU): the 8
 * dimensions of one path vertex share a cache line, and a CPU work-item reads them with one
 * miss where dimension-major costs eight; the walks see compacted, shuffled chains anyway. */
HELPER size_t mlt_index(uint dim, uint chain, uint chains) {
#if MLT_CHAIN_MAJOR
    return (size_t)chain * MLT_MAX_DIMS + dim;
#else
    return (size_t)dim * chains + chain;
#endif
}

HELPER Sampler mlt_mutation_sampler(uint seed, int chain, int iteration) {
    return sampler_init(seed ^ MLT_MUTATION_KEY, (uint)chain, (uint)iteration);
}

/* The fresh value of dimension `dim` (after the mutation's own two: the step and the acceptance). */
HELPER float mlt_fresh(Sampler* mutation, uint dim) { return sampler_get(mutation, 2u + dim); }

typedef struct {
    Sampler fresh;                   /* the mutation's random numbers: the fresh dimensions */
    __global const float* primary;   /* the proposals: primary[mlt_index(dim, chain, chains)] */
    uint chains, chain;
} MltProposal;

/* Dimension `dim` of the proposal: stored (perturbed) or fresh. */
HELPER float mlt_proposal_dim(MltProposal* proposal, uint dim) {
    float u = dim < MLT_MAX_DIMS ? proposal->primary[mlt_index(dim, proposal->chain, proposal->chains)] : MLT_FRESH;
    return u >= 0.0f ? u : mlt_fresh(&proposal->fresh, dim);
}

#endif
