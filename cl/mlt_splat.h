/* The splats of Metropolis's chains, and b, on the device (host: toolkit/techniques/mlt.py, whose
 * docstring derives the weights). Nothing here is read back during the render: the host reads
 * the two films and b once, for the image.
 *
 * Records. A chain's proposal keeps its connection records (value, pixel) in the proposal store,
 * copied there by mlt_proposal_sums (cl/mlt_contribution.h); its current state keeps its records
 * in the current store. Each store is three arrays, one entry per record: value (float4, .w is
 * the record's splat weight, set before each splat), pixel (-1: none) and chain; and per chain
 * its span (int2: the first entry and the count of its records). After the acceptance mlt_keep_records writes the
 * next current store: each chain's accepted proposal's records, or its old current records.
 *
 * Splats. mlt_accept_and_weigh gives every chain three weights (mlt_chain_splat_weights, before
 * its acceptance overwrites the current state's f): the proposal's a w / (f(y) + p b'), the current state's (1 - a) w /
 * (f(x) + p b') and, with Kelemen's combination, a large step's own b' / (f(y) + p b'); w is the
 * chain's weight (start = resample), b' the estimate of b before this iteration. mlt_weigh_records
 * puts one of them in each record's .w, and the record film (cl/record_film.cl) adds value * .w:
 * exact integer sums, so the image's bits do not depend on the order of the additions.
 *
 * b, the mean f of the large steps, is summed exactly too: each large step adds its f, in fixed
 * point (units of 2^unit_exponent, the record film's fixed_point), to one 128-bit integer with
 * integer atomics, and counts itself in tallies[MLT_TALLY_LARGE_STEPS]; mlt_estimate_b turns the
 * sum into the float b' that the next iteration weighs with. */
#ifndef MLT_SPLAT_H
#define MLT_SPLAT_H

#include "common.h"
#include "fixed_point_128.h"
#include "mlt.h"

/* A large step's f into b's exact sum, in fixed point (units of 2^unit_exponent), and its count
 * into tallies[MLT_TALLY_LARGE_STEPS]. */
HELPER void mlt_add_to_b(float fy, const int unit_exponent, __global FilmAccumulator* b_sum, __global int* tallies)
{
    float units = fy * ldexp(1.0f, -unit_exponent);
    if (units > FILM_RECORD_LIMIT) {          /* far brighter than any light: a bug, reported */
        atomic_inc(&tallies[MLT_TALLY_NONFINITE]);
        units = 0.0f;
    }
    uint4 x = fixed_point(units);
    if (!is_zero_128(x)) atomic_add_128(channel_words(b_sum, 0, 0), x);
    atomic_inc(&tallies[MLT_TALLY_LARGE_STEPS]);
}

/* Chain c's splat weights (.x proposal, .y current state, .z a large step's own; zero outside
 * MLT_MUTATE) and its large step's f into b's sum; before its acceptance changes the current state. */
HELPER void mlt_chain_splat_weights(const MltIteration it, int c, MltChain chain, float fy,
                                    __global const float* weight, __global const float* b_estimate,
                                    const int combine, const int unit_exponent, __global float4* splat_weights,
                                    __global FilmAccumulator* b_sum, __global int* tallies)
{
    bool large = chain.large_step != 0;
    float4 w = (float4)(0.0f);
    if (it.mode == MLT_MUTATE) {
        float a = mlt_acceptance(chain.f_current, fy);
        float b = b_estimate[0];
        float mix = combine ? it.large_step * b : 0.0f;   /* p b': the large steps' density, in f's units */
        float d_proposal = fy + mix, d_current = chain.f_current + mix;
        w.x = d_proposal > 0.0f ? a * weight[c] / d_proposal : 0.0f;
        w.y = d_current > 0.0f ? (1.0f - a) * weight[c] / d_current : 0.0f;
        w.z = combine && large && d_proposal > 0.0f ? b / d_proposal : 0.0f;
    }
    splat_weights[c] = w;
    if (large) mlt_add_to_b(fy, unit_exponent, b_sum, tallies);
}

/* Every active chain: its splat weights from a (mlt_chain_splat_weights, while its current state
 * is still the old one), then its acceptance (cl/mlt.h mlt_accept_chain). One launch for both. */
__kernel void mlt_accept_and_weigh(const MltIteration it, __global float* current, __global const float* proposal,
                                   __global MltChain* chains, __global const float* f_proposal,
                                   __global const int* dims_proposal, __global const float* weight,
                                   __global const float* b_estimate, const int combine,
                                   __global float4* splat_weights, __global FilmAccumulator* b_sum,
                                   __global int* tallies)
{
    int c = get_global_id(0);
    if (c >= it.active) return;
    mlt_chain_splat_weights(it, c, chains[c], f_proposal[c], weight, b_estimate, combine, it.unit_exponent,
                            splat_weights, b_sum, tallies);
    mlt_accept_chain(it, c, current, proposal, chains, f_proposal, dims_proposal);
}

/* b' = b's sum / the large steps so far, for the next iteration's weights (work-item 0 of
 * mlt_keep_records: b's sum is complete once mlt_accept_and_weigh has run). */
HELPER void mlt_estimate_b(__global FilmAccumulator* b_sum, const int unit_exponent,
                           __global const int* tallies, __global float* b_estimate)
{
    float sum = ldexp(fixed_to_float(load_128(channel_words(b_sum, 0, 0))), unit_exponent);
    b_estimate[0] = sum / (float)max(tallies[MLT_TALLY_LARGE_STEPS], 1);
}

/* start = resample: chain c's weight w_c / mean(w) with w_c its candidates' sum of f; the mean
 * over the chains is b's sum over the count of chains (the start's large steps are the candidates).
 * All zero (no light found): the weights stay 1. */
__kernel void mlt_resample_weights(const MltIteration it, __global const MltChain* chains,
                                   __global FilmAccumulator* b_sum, __global float* weight)
{
    int c = get_global_id(0);
    if (c >= it.active) return;
    float sum = ldexp(fixed_to_float(load_128(channel_words(b_sum, 0, 0))), it.unit_exponent);
    if (sum > 0.0f) weight[c] = chains[c].candidates * (float)it.chains / sum;
}

/* Record i of a store gets the weight `component` (0 proposal, 1 current, 2 large step) of its
 * chain, or 0 for a chain that is not active in this iteration. `total`: the store's records
 * (on the device); the launch covers `capacity`, the host's bound on them, and the film's
 * addition after it as many: an entry past the total (left from an earlier iteration) gets
 * pixel -1, so it splats nothing (no fill of the store before each rebuild). */
__kernel void mlt_weigh_records(const int capacity, __global const int* total, const int active,
                                const int component, __global const float4* splat_weights,
                                __global const int* record_chain, __global float4* record_value,
                                __global int* record_pixel)
{
    int i = get_global_id(0);
    if (i >= capacity) return;
    if (i >= total[0]) {
        record_pixel[i] = -1;
        return;
    }
    int c = record_chain[i];
    /* c < 0 or past the chains: an entry that mlt_keep_records reserved but did not write (the
     * store overflowed, which the render reports): weight 0, never an index out of bounds */
    float4 w = c >= 0 && c < active ? splat_weights[c] : (float4)(0.0f);
    record_value[i].w = component == 0 ? w.x : component == 1 ? w.y : w.z;
}

/* Chain c's records, `span` (first entry, count) of value and pixel, into the next current store
 * at entries taken with the atomic counter next_total. Past `capacity` nothing is written: the
 * records are counted in tallies[MLT_TALLY_STORE_OVERFLOW] (the host's bound was wrong: reported). */
HELPER void mlt_store_records(int c, int2 span, __global const float4* value, __global const int* pixel,
                              int capacity, __global int2* next_span, __global float4* next_value,
                              __global int* next_pixel, __global int* next_chain, __global int* next_total,
                              __global int* tallies)
{
    int first = span.y > 0 ? atomic_add(next_total, span.y) : 0;
    if (first + span.y > capacity) {
        atomic_add(&tallies[MLT_TALLY_STORE_OVERFLOW], span.y);
        for (int k = first; k < capacity; ++k)   /* reserved below the end: no pixel, no splat */
            next_pixel[k] = -1;
        next_span[c] = (int2)(0, 0);
        return;
    }
    for (int k = 0; k < span.y; ++k) {
        next_value[first + k] = value[span.x + k];
        next_pixel[first + k] = pixel[span.x + k];
        next_chain[first + k] = c;
    }
    next_span[c] = (int2)(first, span.y);
}

/* The next current store: chain c keeps its accepted proposal's records, or its current ones
 * (chains past it.active did not mutate). Entries are taken with an atomic counter, next_total:
 * their order changes from run to run, the film's integer sums do not. Counts the accepted
 * mutations, and the records past `capacity` (none: the host bounds the store's size). Work-item 0
 * also estimates b for the next iteration (mlt_estimate_b): one launch less per iteration. */
__kernel void mlt_keep_records(const MltIteration it, __global const MltChain* chains,
                               __global const int2* proposal_span, __global const float4* proposal_value,
                               __global const int* proposal_pixel, __global const int2* current_span,
                               __global const float4* current_value, __global const int* current_pixel,
                               __global int2* next_span, __global float4* next_value, __global int* next_pixel,
                               __global int* next_chain, __global int* next_total, __global int* tallies,
                               __global FilmAccumulator* b_sum, __global float* b_estimate)
{
    int c = get_global_id(0);
    int capacity = it.store_capacity;
    if (c == 0) mlt_estimate_b(b_sum, it.unit_exponent, tallies, b_estimate);
    if (c >= it.chains) return;
    bool accepted = c < it.active && chains[c].accepted;
    if (accepted && it.mode == MLT_MUTATE) atomic_inc(&tallies[MLT_TALLY_ACCEPTED]);
    if (accepted)
        mlt_store_records(c, proposal_span[c], proposal_value, proposal_pixel, capacity, next_span, next_value,
                          next_pixel, next_chain, next_total, tallies);
    else
        mlt_store_records(c, current_span[c], current_value, current_pixel, capacity, next_span, next_value,
                          next_pixel, next_chain, next_total, tallies);
}

#endif
