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

#if FILM_WORD_BITS == 64
#pragma OPENCL EXTENSION cl_khr_int64_base_atomics : enable
#endif

/* Channel c's four words of pixel p. */
HELPER volatile __global uint* channel_words(__global FilmAccumulator* film, int p, int c) {
    return (volatile __global uint*)&film[p].red + 4 * c;
}

/* The carry out of sum = a + b (+ a carry in): from the top bits alone (it is 1 where a and b
 * both have it, or either has it and the sum does not). Bit arithmetic, not a comparison
 * turned into 0 or 1: Oclgrind 21.10 gives 255 for `x < y ? 1u : 0u`. */
HELPER uint carry_out(uint a, uint b, uint sum) { return ((a & b) | ((a | b) & ~sum)) >> 31; }
HELPER ulong carry_out_64(ulong a, ulong b, ulong sum) { return ((a & b) | ((a | b) & ~sum)) >> 63; }

/* Two's complement negation of a 128-bit integer in four words (least significant first). */
HELPER uint4 negated(uint4 w) {
    w = ~w;
    w.x += 1u;
    if (w.x == 0u) { w.y += 1u; if (w.y == 0u) { w.z += 1u; if (w.z == 0u) w.w += 1u; } }
    return w;
}

/* A record's value v (finite, |v| <= FILM_RECORD_LIMIT) in units of 2^-FILM_FRACTION_BITS, rounded
 * to nearest (ties to even), as 128 bits. Read from the float's own bits, in integer arithmetic
 * only: |v| = m * 2^(e - 150) with m its 24-bit mantissa, so |v| * 2^48 = m * 2^shift. A left
 * shift places m in the words exactly; a right shift (records below 2^-25) rounds. */
HELPER uint4 fixed_point(float v) {
    uint bits = as_uint(v);
    int e = (int)((bits >> 23) & 0xffu);
    if (e == 0) return (uint4)(0u);                   /* zero, or below 2^-126: far below 2^-48 */
    uint m = (bits & 0x7fffffu) | 0x800000u;
    int shift = e - 150 + FILM_FRACTION_BITS;
    uint4 w = (uint4)(0u);
    if (shift < 0) {
        if (shift < -24) return (uint4)(0u);          /* below half a unit */
        uint s = (uint)(-shift);
        /* round half to even: add half a unit less one, plus the kept part's last bit */
        w.x = (m + ((1u << (s - 1u)) - 1u) + ((m >> s) & 1u)) >> s;
    } else {
        ulong x = (ulong)m << (shift & 31);           /* at most 55 bits: two words */
        uint low = (uint)x, high = (uint)(x >> 32);
        int k = shift >> 5;                           /* shift <= 72 (FILM_RECORD_LIMIT): k <= 2 */
        if (k == 0) { w.x = low; w.y = high; }
        else if (k == 1) { w.y = low; w.z = high; }
        else { w.z = low; w.w = high; }
    }
    if (bits >> 31) w = negated(w);
    return w;
}

#if FILM_WORD_BITS == 64
/* words += x (mod 2^128) as two 64-bit atomics; a wrapped low word carries into the high one. */
HELPER void atomic_add_128(volatile __global uint* words, uint4 x) {
    volatile __global ulong* w = (volatile __global ulong*)words;
    ulong low = upsample(x.y, x.x), high = upsample(x.w, x.z);
    if (low != 0ul) {
        ulong old = atom_add(&w[0], low);
        high += carry_out_64(old, low, old + low);   /* this addition wrapped the low word */
    }
    if (high != 0ul) atom_add(&w[1], high);
}

HELPER uint4 load_128(volatile __global uint* words) {
    volatile __global ulong* w = (volatile __global ulong*)words;
    ulong low = w[0], high = w[1];
    return (uint4)((uint)low, (uint)(low >> 32), (uint)high, (uint)(high >> 32));
}

HELPER void clear_128(volatile __global uint* words) {
    volatile __global ulong* w = (volatile __global ulong*)words;
    w[0] = 0ul;
    w[1] = 0ul;
}
#else
/* words += x (mod 2^128) as 32-bit atomics, word by word, each carry added with the next word. */
HELPER void atomic_add_128(volatile __global uint* words, uint4 x) {
    uint part[4] = {x.x, x.y, x.z, x.w};
    uint carry = 0u;
    for (int k = 0; k < 4; ++k) {
        uint add = part[k] + carry;
        carry = carry_out(part[k], carry, add);     /* part + carry wrapped (to 0: nothing to add) */
        if (add != 0u) {
            uint old = atomic_add(&words[k], add);
            carry += carry_out(old, add, old + add);   /* this addition wrapped word k */
        }
    }
}

HELPER uint4 load_128(volatile __global uint* words) {
    return (uint4)(words[0], words[1], words[2], words[3]);
}

HELPER void clear_128(volatile __global uint* words) {
    for (int k = 0; k < 4; ++k) words[k] = 0u;
}
#endif

/* a + b + *carry in one 32-bit word; *carry becomes the carry out. */
HELPER uint add_with_carry(uint a, uint b, uint* carry) {
    uint sum = a + b + *carry;
    *carry = carry_out(a, b, sum);
    return sum;
}

/* a + b (mod 2^128) in registers: each word's carry goes into the next. */
HELPER uint4 add_128(uint4 a, uint4 b) {
    uint carry = 0u;
    uint4 s;
    s.x = add_with_carry(a.x, b.x, &carry);
    s.y = add_with_carry(a.y, b.y, &carry);
    s.z = add_with_carry(a.z, b.z, &carry);
    s.w = add_with_carry(a.w, b.w, &carry);
    return s;
}

HELPER bool is_zero_128(uint4 w) { return (w.x | w.y | w.z | w.w) == 0u; }

/* A run of records on pixel p (none where p < 0), summed per channel, into the film. */
HELPER void add_run(__global FilmAccumulator* film, int p, uint4 red, uint4 green, uint4 blue) {
    if (p < 0) return;
    if (!is_zero_128(red)) atomic_add_128(channel_words(film, p, 0), red);
    if (!is_zero_128(green)) atomic_add_128(channel_words(film, p, 1), green);
    if (!is_zero_128(blue)) atomic_add_128(channel_words(film, p, 2), blue);
}

/* The 128-bit sum w (units of 2^-FILM_FRACTION_BITS) rounded to the nearest float: the 64 bits
 * from its highest nonzero word down go to convert_float_rte; a one in their last bit stands for
 * any nonzero bit below them (a "sticky" bit, far below float's 24 bits), so the rounding of a
 * tie is decided as if every bit were there. */
HELPER ulong sticky(uint bits) { return ((ulong)bits + 0xfffffffful) >> 32; }   /* 1 where bits != 0 */

HELPER float fixed_to_float(uint4 w) {
    bool negative = (w.w >> 31) != 0u;
    if (negative) w = negated(w);
    ulong window;
    int shift;
    if (w.w != 0u) {
        window = upsample(w.w, w.z) | sticky(w.y | w.x);
        shift = 64;
    } else if (w.z != 0u) {
        window = upsample(w.z, w.y) | sticky(w.x);
        shift = 32;
    } else {
        window = upsample(w.y, w.x);
        shift = 0;
    }
    float magnitude = ldexp(convert_float_rte(window), shift - FILM_FRACTION_BITS);
    if (negative) magnitude = -magnitude;
    return magnitude;
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
