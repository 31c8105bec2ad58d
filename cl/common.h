/* Shared definitions included by every kernel. Feature switches (HAS_DIFFUSE, ...) come as
 * -D defines from toolkit/core/scene.py: code for what a scene does not use is not compiled.
 *
 * Every helper in cl/ is declared HELPER (below), that is `static inline __attribute__((always_inline))`: static
 * semantics on GPU compilers, always_inline because PoCL 3.0 left even one-line helpers as
 * calls (inlining them made pt_naive 19-35% faster on the CPU; tests/test_portability.py holds
 * the rule). OpenCL's own built-ins are calls on PoCL too: the simple ones are written out in
 * inline_builtins.h, sin and cos here (unit_circle), the vector fmin and fmax in bvh.h (minN, maxN). */
#ifndef COMMON_H
#define COMMON_H

/* Every helper function: see above. Written once here; layout.h (generated) uses it too. */
#define HELPER static inline __attribute__((always_inline))

/* Before layout.h, whose records have fields named like built-ins (inline_builtins.h says why). */
#include "inline_builtins.h"
#include "layout.h"

#define PI 3.14159265358979f
#define INV_PI 0.31830988618379f

/* HARD_MAX_BOUNCES (layout.h): where paths without a depth limit or roulette still stop. */

HELPER float max3(float3 v) { return fmax(v.x, fmax(v.y, v.z)); }
HELPER float luminance(float3 c) { return LUMINANCE_R * c.x + LUMINANCE_G * c.y + LUMINANCE_B * c.z; }
HELPER bool is_black(float3 c) { return c.x <= 0.0f && c.y <= 0.0f && c.z <= 0.0f; }
HELPER bool all_finite(float3 c) { return isfinite(c.x) && isfinite(c.y) && isfinite(c.z); }

/* An orthonormal basis around unit n (Duff et al. 2017, "Building an Orthonormal Basis, Revisited"). */
HELPER void make_basis(float3 n, float3* s, float3* t) {
    float sign = copysign(1.0f, n.z);
    float a = -1.0f / (sign + n.z);
    float b = n.x * n.y * a;
    *s = (float3)(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x);
    *t = (float3)(b, sign + n.y * n.y * a, -n.y);
}
HELPER float3 to_local(float3 v, float3 s, float3 t, float3 n) { return (float3)(dot(v, s), dot(v, t), dot(v, n)); }
HELPER float3 to_world(float3 v, float3 s, float3 t, float3 n) { return v.x * s + v.y * t + v.z * n; }

/* (cos, sin) of 2 pi u for u in [0, 1): the angle of a uniform point on a circle. PoCL's sin and
 * cos are library calls with a reduction for any argument (11% of pt_naive in perf); here the
 * quadrant is floor(4u), and within it y = x - pi/4 lies in [-pi/4, pi/4), where Taylor
 * series to y^9 and y^10 are exact to 2e-9, below float rounding. */
HELPER float2 unit_circle(float u) {
    float four_u = 4.0f * u;
    int quadrant = (int)four_u;             /* 0 .. 3: u < 1 */
    float y = (four_u - (float)quadrant) * (0.5f * PI) - 0.25f * PI, y2 = y * y;
    float sin_y = y * (1.0f + y2 * (-1.0f / 6.0f + y2 * (1.0f / 120.0f + y2 * (-1.0f / 5040.0f + y2 * (1.0f / 362880.0f)))));
    float cos_y = 1.0f + y2 * (-0.5f + y2 * (1.0f / 24.0f + y2 * (-1.0f / 720.0f + y2 * (1.0f / 40320.0f + y2 * (-1.0f / 3628800.0f)))));
    float c = (cos_y - sin_y) * M_SQRT1_2_F, s = (cos_y + sin_y) * M_SQRT1_2_F;   /* x = y + pi/4 */
    return quadrant == 0 ? (float2)(c, s) : quadrant == 1 ? (float2)(-s, c) : quadrant == 2 ? (float2)(-c, -s) : (float2)(s, -c);
}

/* Cosine-weighted hemisphere (Malley's method: a uniform disk point lifted to the hemisphere). */
HELPER float3 sample_cosine_hemisphere(float u1, float u2) {
    float r = sqrt(u1);
    float2 circle = unit_circle(u2);
    return (float3)(r * circle.x, r * circle.y, sqrt(fmax(0.0f, 1.0f - u1)));
}

/* Russian roulette (as Mitsuba 3's path integrator): continue with probability
 * q = min(max(throughput) / normaliser, 0.95), using the uniform number u, and divide the
 * throughput by q (no change in expectation). Path tracers pass normaliser 1; BDPT light
 * paths pass their throughput at y_1 (cl/bdpt_walk.h). Returns false when the path stops. */
HELPER bool roulette(float3* throughput, float normaliser, float u) {
    float q = fmin(max3(*throughput) / normaliser, 0.95f);
    if (u >= q) return false;
    *throughput /= q;
    return true;
}

/* Power heuristic (Veach 1997, eq. 9.13, beta = 2) for two strategies with pdfs a and b. */
HELPER float power_heuristic(float a, float b) {
    float a2 = a * a, b2 = b * b;
    return a2 > 0.0f ? a2 / (a2 + b2) : 0.0f;
}

#endif
