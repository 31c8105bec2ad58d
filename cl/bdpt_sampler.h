/* The one hook through which the BDPT code (cl/bdpt_walk.h) reads its uniforms: a BdptSampler,
 * asked for dimension `dim` of the sample (the table of toolkit/core/sample_dims.py:
 * BDPT_DIM_*, bdpt_scatter_dim in layout.h). Built for bidirectional path tracing it is the
 * Philox sampler (cl/philox.h). Built with -DMLT=1 (toolkit/techniques/mlt.py) it answers from
 * the chain's proposal (cl/mlt_proposals.h), so the same walk and connect code evaluates
 * Metropolis proposals. */
#ifndef BDPT_SAMPLER_H
#define BDPT_SAMPLER_H

#include "common.h"
#include "philox.h"

#if MLT
#include "mlt_proposals.h"
typedef MltProposal BdptSampler;
HELPER float bdpt_sample(BdptSampler* rng, uint dim) { return mlt_proposal_dim(rng, dim); }
/* The extra kernel parameter (and argument) that carries the vectors to the BDPT kernels. */
#define BDPT_SAMPLER_PARAM , __global const float* mlt_primary
#define BDPT_SAMPLER_ARG , mlt_primary
#else
typedef Sampler BdptSampler;
HELPER float bdpt_sample(BdptSampler* rng, uint dim) { return sampler_get(rng, dim); }
#define BDPT_SAMPLER_PARAM
#define BDPT_SAMPLER_ARG
#endif

#endif
