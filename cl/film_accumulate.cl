/* A path-tracing film kept on the device (host: toolkit/opencl/device_film.py): each pass's
 * FilmPixel sums (cl/film_reduce.cl) are added here in float64, so the host reads the film once,
 * when it is asked for, instead of every pass's sums.
 *
 * The host film adds the same float32 pass sums in float64, pass after pass
 * (toolkit/core/film.py). Converting a float to a double is exact and a double addition is
 * correctly rounded (IEEE 754), so adding the same values in the same order gives the same bits
 * here: a device with cl_khr_fp64 renders the host path's image bit for bit. */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#include "common.h"

/* One work-item per pixel: sums holds 6 doubles per pixel (the sums of r, g, b, then of their
 * squares), counts 2 ints (the samples missing, then dropped: FilmPixel's fields of those names). */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void film_accumulate(__global const FilmPixel* pass, const int pixels, __global double* sums, __global int* counts)
{
    int p = get_global_id(0);
    if (p >= pixels) return;
    FilmPixel f = pass[p];
    __global double* s = sums + 6 * p;
    s[0] += (double)f.sum.x;
    s[1] += (double)f.sum.y;
    s[2] += (double)f.sum.z;
    s[3] += (double)f.sum_sq.x;
    s[4] += (double)f.sum_sq.y;
    s[5] += (double)f.sum_sq.z;
    counts[2 * p] += f.missing;
    counts[2 * p + 1] += f.dropped;
}

/* A BDPT pass's image (cl/record_film.cl's resolve: float4 per pixel, the RGB sums of its records
 * and in .w the records dropped there), added as the host film's add_pass adds it
 * (toolkit/core/film.py): the pass's mean v = sum / spp, then spp * v and spp * v * v into the sums.
 * The same operations in the same order: the host's bits, provided no multiply and add are fused
 * into one rounding (FP_CONTRACT OFF). */
#pragma OPENCL FP_CONTRACT OFF
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void film_accumulate_pass(__global const float4* image, const int spp, const int pixels,
                          __global double* sums, __global int* counts)
{
    int p = get_global_id(0);
    if (p >= pixels) return;
    float4 f = image[p];
    const double n = (double)spp;
    const double v[3] = {(double)f.x / n, (double)f.y / n, (double)f.z / n};
    __global double* s = sums + 6 * p;
    for (int c = 0; c < 3; c++) {
        s[c] += n * v[c];
        s[3 + c] += n * (v[c] * v[c]);
    }
    counts[2 * p + 1] += (int)f.w;
}
