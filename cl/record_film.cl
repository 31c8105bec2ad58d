/* Connection records (value, pixel) summed per pixel on the device (host: toolkit/opencl/record_film.py).
 *
 * BDPT's connect phases write one record per connection, and a light-tracing (t = 1) record
 * lands on any pixel: many work-items add to one pixel at once. Float atomics would make the
 * sum depend on the order of the additions (the image's bits would change from run to run) and
 * OpenCL 1.2 has none. Integer additions give the same bits in any order. So each record is
 * rounded to a fixed point, a multiple of 2^-FILM_FRACTION_BITS (2^-48), and added with integer
 * atomics into 128 bits per channel (FilmAccumulator, toolkit/core/layout.py says why 48 and 128):
 * a record of 1e-6 is kept exactly, and 2^31 records of 1e14 still fit. Records are counted in
 * units of 2^unit_exponent, a power of two near the scene's brightest light (the host's choice),
 * so a scene 1e6 times darker or brighter keeps the same precision: scaling by a power of two
 * is exact, and its image is the same bits scaled.
 *
 * Two ways to add 128 bits, the same bits in the end (tests/test_record_film.py):
 *   FILM_WORD_BITS 64: two 64-bit words with atom_add (cl_khr_int64_base_atomics, most devices);
 *   FILM_WORD_BITS 32: four 32-bit words with atomic_add (OpenCL 1.1's core, every device).
 * A word that wraps around carries one into the next: atomic_add returns the word's old value,
 * so the work-item whose addition wrapped it knows, and adds the carry itself. Every carry is
 * added exactly once, so the words end as the exact sum modulo 2^128, whatever the order.
 *
 * At the end of a pass record_film_resolve rounds each sum to the nearest float (once, so the
 * pass's pixel is within half an ulp of the exact sum of its rounded records), writes it for the
 * host to read and zeroes the sums for the next pass. */
#include "common.h"
#include "fixed_point_128.h"

/* A run of records on pixel p (none where p < 0), summed per channel, into the film. */
HELPER void add_run(__global FilmAccumulator* film, int p, uint4 red, uint4 green, uint4 blue) {
    if (p < 0) return;
    if (!is_zero_128(red)) atomic_add_128(channel_words(film, p, 0), red);
    if (!is_zero_128(green)) atomic_add_128(channel_words(film, p, 1), green);
    if (!is_zero_128(blue)) atomic_add_128(channel_words(film, p, 2), blue);
}

/* Each work-item adds FILM_RECORDS_PER_ITEM consecutive records: each its value (RGB; with
 * `weighted`, the records of the STRATEGY_IMAGES kernels, RGB times the MIS weight in .w) to its
 * pixel. A sample's connections are consecutive and most land on its own pixel, so a run of
 * records on one pixel is summed in registers first, then added with one atomic per word: integer
 * sums are exact, so this changes no bit of the result, only how many atomics contend for a pixel. A record of pixel -1 was
 * left unwritten by its connect phase; one whose value is not finite or beyond FILM_RECORD_LIMIT
 * units is counted in its pixel's `dropped` (DroppedSamplesWarning reports it), never added. */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void record_film_add(__global const float4* record_value, __global const int* record_pixel, const int count,
                     const int weighted, const int unit_exponent, const int pixels, __global FilmAccumulator* film)
{
    int first = get_global_id(0) * FILM_RECORDS_PER_ITEM;
    int run = -1;                       /* the pixel of the run summed so far, -1: none yet */
    float unit = ldexp(1.0f, -unit_exponent);   /* exact: a power of two (Oclgrind's vector ldexp is not) */
    uint4 red = (uint4)(0u), green = (uint4)(0u), blue = (uint4)(0u);
    for (int i = first; i < min(first + FILM_RECORDS_PER_ITEM, count); ++i) {
        int p = record_pixel[i];
        if (p < 0 || p >= pixels) continue;
        float4 v = record_value[i];
        float3 value = v.xyz;
        if (weighted) value *= v.w;
        value *= unit;                  /* in units of 2^unit_exponent */
        if (!all_finite(value) || max3(fabs(value)) > FILM_RECORD_LIMIT) {
            atomic_inc(&film[p].dropped);
            continue;
        }
        if (p != run) {                 /* a new run: the last one goes to the film */
            add_run(film, run, red, green, blue);
            run = p;
            red = green = blue = (uint4)(0u);
        }
        red = add_128(red, fixed_point(value.x));
        green = add_128(green, fixed_point(value.y));
        blue = add_128(blue, fixed_point(value.z));
    }
    add_run(film, run, red, green, blue);
}

/* One work-item per pixel, after a pass's last record_film_add: out[p] = (the pass's RGB sums,
 * rounded to float, and in .w the records dropped there); the pixel's sums start again at zero. */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void record_film_resolve(__global FilmAccumulator* film, const int unit_exponent, const int pixels,
                         __global float4* out)
{
    int p = get_global_id(0);
    if (p >= pixels) return;
    float4 sums;
    sums.x = ldexp(fixed_to_float(load_128(channel_words(film, p, 0))), unit_exponent);
    sums.y = ldexp(fixed_to_float(load_128(channel_words(film, p, 1))), unit_exponent);
    sums.z = ldexp(fixed_to_float(load_128(channel_words(film, p, 2))), unit_exponent);
    sums.w = (float)film[p].dropped;
    out[p] = sums;
    for (int c = 0; c < 3; ++c) clear_128(channel_words(film, p, c));
    film[p].dropped = 0u;
}
