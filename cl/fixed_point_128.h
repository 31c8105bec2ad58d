/* Exact 128-bit fixed-point sums (cl/record_film.cl explains the design): a float rounded to a
 * multiple of 2^-FILM_FRACTION_BITS as four 32-bit words in two's complement, added with integer
 * atomics (64-bit ones where FILM_WORD_BITS is 64) or in registers, and turned back into the
 * nearest float. The record film sums pixels with them; Metropolis's b is one such sum too
 * (cl/mlt_splat.h). */
#ifndef FIXED_POINT_128_H
#define FIXED_POINT_128_H

#include "common.h"

#ifndef FILM_WORD_BITS
#error "FILM_WORD_BITS (32 or 64: the atomics the sums use) comes from the host: toolkit/opencl/record_film.py film_word_bits"
#endif

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

#endif
