/* Counter-based random numbers: Philox4x32-10 (Salmon et al. 2011, shipped with pyopencl).
 * Every number is a pure function of (seed, pixel, sample, dimension), so an image does not
 * depend on how work-items are scheduled, and a technique may draw dimensions in any order.
 * One Philox call yields a block of four dimensions. Which dimension each sampling decision
 * reads is the sample-dimension table of toolkit/core/sample_dims.py (DIM_*, bounce_dim,
 * BDPT_DIM_*, bdpt_scatter_dim in layout.h). */
#ifndef PHILOX_H
#define PHILOX_H

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

#endif
