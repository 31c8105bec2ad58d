/* Shared definitions included by every kernel. Feature switches (HAS_DIFFUSE, ...) come as
 * -D defines from toolkit/scene.py: code for what a scene does not use is not compiled. */
#ifndef COMMON_H
#define COMMON_H

#include "layout.h"

#define PI 3.14159265358979f
#define INV_PI 0.31830988618379f

/* Paths without a depth limit or roulette still stop here; a path this long carries
 * no measurable energy in any scene whose albedo is below one. */
#define HARD_MAX_BOUNCES 1024

static inline float max3(float3 v) { return fmax(v.x, fmax(v.y, v.z)); }
static inline float luminance(float3 c) { return LUMINANCE_R * c.x + LUMINANCE_G * c.y + LUMINANCE_B * c.z; }
static inline bool is_black(float3 c) { return c.x <= 0.0f && c.y <= 0.0f && c.z <= 0.0f; }
static inline bool all_finite(float3 c) { return isfinite(c.x) && isfinite(c.y) && isfinite(c.z); }

/* An orthonormal basis around unit n (Duff et al. 2017, "Building an Orthonormal Basis, Revisited"). */
static inline void make_basis(float3 n, float3* s, float3* t) {
    float sign = copysign(1.0f, n.z);
    float a = -1.0f / (sign + n.z);
    float b = n.x * n.y * a;
    *s = (float3)(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x);
    *t = (float3)(b, sign + n.y * n.y * a, -n.y);
}
static inline float3 to_local(float3 v, float3 s, float3 t, float3 n) { return (float3)(dot(v, s), dot(v, t), dot(v, n)); }
static inline float3 to_world(float3 v, float3 s, float3 t, float3 n) { return v.x * s + v.y * t + v.z * n; }

/* Cosine-weighted hemisphere (Malley's method: a uniform disk point lifted to the hemisphere). */
static inline float3 sample_cosine_hemisphere(float u1, float u2) {
    float r = sqrt(u1), phi = 2.0f * PI * u2;
    return (float3)(r * cos(phi), r * sin(phi), sqrt(fmax(0.0f, 1.0f - u1)));
}

/* Russian roulette (as Mitsuba 3's path integrator): continue with probability
 * q = min(max(throughput) / normaliser, 0.95), using the uniform number u, and divide the
 * throughput by q (no change in expectation). Path tracers pass normaliser 1; BDPT light
 * paths pass their throughput at y_1 (cl/bdpt_walk.h). Returns false when the path stops. */
static inline bool roulette(float3* throughput, float normaliser, float u) {
    float q = fmin(max3(*throughput) / normaliser, 0.95f);
    if (u >= q) return false;
    *throughput /= q;
    return true;
}

/* Power heuristic (Veach 1997, eq. 9.13, beta = 2) for two strategies with pdfs a and b. */
static inline float power_heuristic(float a, float b) {
    float a2 = a * a, b2 = b * b;
    return a2 > 0.0f ? a2 / (a2 + b2) : 0.0f;
}

#endif
