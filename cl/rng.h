/* Counter-based random numbers: Philox4x32-10 (Salmon et al. 2011, shipped with pyopencl).
 * Every number is a pure function of (seed, pixel, sample, dimension), so an image does not
 * depend on how work-items are scheduled, and a technique may draw dimensions in any order.
 * One Philox call yields a block of four dimensions. */
#ifndef RNG_H
#define RNG_H

#include "common.h"

#include <pyopencl-random123/philox.cl>

typedef struct {
    uint seed, pixel, sample;
    uint block;      /* block currently held in `cache`, or 0xffffffff */
    float4 cache;
    uint dim;        /* next dimension for sampler_next() */
} Sampler;

HELPER float uint_to_unit(uint x) { return (float)(x >> 8) * (1.0f / 16777216.0f); /* in [0, 1) */ }

HELPER float4 rng_block(uint seed, uint pixel, uint sample, uint block) {
    philox4x32_ctr_t counter = {{pixel, sample, block, 0x6d6c7421u}};
    philox4x32_key_t key = {{seed, 0x9e3779b9u}};
    philox4x32_ctr_t r = philox4x32(counter, key);
    return (float4)(uint_to_unit(r.v[0]), uint_to_unit(r.v[1]), uint_to_unit(r.v[2]), uint_to_unit(r.v[3]));
}

HELPER Sampler sampler_init(uint seed, uint pixel, uint sample) {
    Sampler s = {seed, pixel, sample, 0xffffffffu, (float4)(0.0f), 0};
    return s;
}

/* The uniform number of dimension `dim` of this sample. Inlined (as every helper, common.h),
 * a run of reads from one block shares its Philox call. */
HELPER float sampler_get(Sampler* s, uint dim) {
    uint block = dim >> 2;
    if (block != s->block) { s->cache = rng_block(s->seed, s->pixel, s->sample, block); s->block = block; }
    uint k = dim & 3u;
    return k == 0 ? s->cache.x : k == 1 ? s->cache.y : k == 2 ? s->cache.z : s->cache.w;
}

/* Dimension layout of a path-tracing sample: 2 for the pixel position, then
 * DIMS_PER_BOUNCE per bounce (see the DIM_* offsets), so bounce k always reads the same dims. */
#define DIM_PIXEL 0
#define DIMS_PER_BOUNCE 8
#define DIM_LIGHT_PICK 0
#define DIM_LIGHT_U 1
#define DIM_LIGHT_V 2
#define DIM_BSDF_U 3
#define DIM_BSDF_V 4
#define DIM_BSDF_LOBE 5
#define DIM_ROULETTE 6
HELPER uint bounce_dim(int bounce, uint offset) { return 4u + (uint)bounce * DIMS_PER_BOUNCE + offset; }

/* The sampler interface of a bidirectional sample: every random number it consumes is
 * dimension `dim` of sample (pixel, sample). A Metropolis sampler can drive the same BDPT code
 * by answering these calls from a stored, mutated primary-sample vector instead.
 * Fixed assignment of dimensions:
 *     0, 1                pixel position (eye)
 *     2                   which light;  3, 4  point on it;  5, 6  emission direction
 *     8 + 8(k-1) + 0..3   eye vertex k >= 1 scatters:   BSDF u, v, lobe, roulette
 *     8 + 8(k-1) + 4..7   light vertex k >= 1 scatters: BSDF u, v, lobe, roulette
 * Connections consume no random numbers (s = 1 uses the light subpath's first vertex). */
#define BDPT_DIM_PIXEL 0
#define BDPT_DIM_LIGHT_PICK 2
#define BDPT_DIM_LIGHT_POINT 3
#define BDPT_DIM_EMIT_DIR 5
HELPER uint bdpt_scatter_dim(int vertex, bool light_path, uint offset) {
    return 8u + 8u * (uint)(vertex - 1) + (light_path ? 4u : 0u) + offset;
}

/* Metropolis proposals (cl/mlt.h): the uniforms of chain `chain`'s proposal, stored
 * at primary[mlt_index(dim, chain, chains)] (below). A dimension the mutation perturbed holds its
 * value there; a dimension the mutation draws afresh holds the mark MLT_FRESH (< 0), and its
 * value is the mutation's own random number for it, Philox (seed ^ MLT_MUTATION_KEY, chain,
 * iteration), dimension 2 + dim, drawn where it is read. So a large step costs the random
 * numbers its path reads, not MLT_MAX_DIMS of them. Dimensions >= MLT_MAX_DIMS are not stored:
 * always fresh, at every iteration, an independent proposal, which is symmetric too, so the
 * chain stays correct; it only explores such long paths like a large step would (cl/mlt.h). */
#ifndef MLT_MAX_DIMS
#define MLT_MAX_DIMS 128   /* set by the host: 8 + 8 * 15, subpaths of up to 16 vertices */
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
HELPER float mlt_proposal_dim(MltProposal* s, uint dim) {
    float u = dim < MLT_MAX_DIMS ? s->primary[mlt_index(dim, s->chain, s->chains)] : MLT_FRESH;
    return u >= 0.0f ? u : mlt_fresh(&s->fresh, dim);
}

/* The one hook through which the BDPT code (cl/bdpt_walk.h) reads its uniforms: a BdptSampler.
 * Built for bidirectional path tracing it is the Philox sampler above. Built with -DMLT=1
 * (toolkit/techniques/mlt.py) it answers from the chain's proposal (MltProposal above). */
#if MLT
typedef MltProposal BdptSampler;
HELPER float bdpt_sample(BdptSampler* s, uint dim) { return mlt_proposal_dim(s, dim); }
/* The extra kernel parameter (and argument) that carries the vectors to the BDPT kernels. */
#define BDPT_SAMPLER_PARAM , __global const float* mlt_primary
#define BDPT_SAMPLER_ARG , mlt_primary
#else
typedef Sampler BdptSampler;
HELPER float bdpt_sample(BdptSampler* s, uint dim) { return sampler_get(s, dim); }
#define BDPT_SAMPLER_PARAM
#define BDPT_SAMPLER_ARG
#endif

#endif
