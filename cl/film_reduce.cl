/* The samples of a path-tracing pass, summed per pixel on the device (host: toolkit/opencl/film_reduce.py).
 *
 * A pass writes one float4 per sample, pixel-major: sample k of pixel p at k * pixels + p, .w
 * saying whether it was written (-1: never, 0: done, 1: not finite). Reading every sample back
 * costs the host more than the device took to render them on a GPU (an H200 rendered 2.2 million
 * samples in 4 ms of kernels and 60 ms of host sums). So each pixel's samples are summed here and
 * the host reads one FilmPixel per pixel.
 *
 * float32 stops adding small values to a large sum; Kahan's compensated sum keeps the error of
 * a pixel's sum near one rounding whatever the number of samples, and the film adds the pass
 * sums in float64 (toolkit/core/film.py). tests/test_film_reduce.py holds it to that. */
#include "common.h"

/* sum += v with its rounding error carried in `carry` (Kahan 1965). */
HELPER void compensated_add(float3* sum, float3* carry, float3 v) {
    float3 y = v - *carry;
    float3 t = *sum + y;
    *carry = (t - *sum) - y;
    *sum = t;
}

/* One work-item per pixel. `clamp_limit`: firefly clamping (scene integrator.clamp, INFINITY for
 * none): a sample whose largest component m exceeds it is scaled by clamp_limit / m. */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void film_reduce(__global const float4* radiance, const int pixels, const int samples, const float clamp_limit,
                 __global FilmPixel* out)
{
    int p = get_global_id(0);
    if (p >= pixels) return;
    float3 sum = (float3)(0.0f), sum_carry = (float3)(0.0f);
    float3 squares = (float3)(0.0f), squares_carry = (float3)(0.0f);
    int missing = 0, dropped = 0;
    for (int k = 0; k < samples; ++k) {
        float4 v = radiance[k * pixels + p];     /* k * pixels + p < the pass's budget < 2^31 */
        if (v.w < 0.0f) { ++missing; continue; }
        if (v.w != 0.0f || !all_finite(v.xyz)) { ++dropped; continue; }
        float m = max3(v.xyz);
        float3 value = m > clamp_limit ? v.xyz * (clamp_limit / m) : v.xyz;
        float3 square = value * value;
        /* above ~1.8e19 a square is no float: such a sample counts as not finite (in float32 the
         * path's own products overflow near there too) */
        if (!all_finite(square)) { ++dropped; continue; }
        compensated_add(&sum, &sum_carry, value);
        compensated_add(&squares, &squares_carry, square);
    }
    FilmPixel f;
    f.sum = (float4)(sum, 0.0f);
    f.sum_sq = (float4)(squares, 0.0f);
    f.missing = missing;
    f.dropped = dropped;
    f.pad0 = 0;
    f.pad1 = 0;
    out[p] = f;
}
