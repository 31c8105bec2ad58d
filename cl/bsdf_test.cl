/* Test kernels for cl/materials.h: draw samples from bsdf_sample and evaluate bsdf_eval at
 * given directions, so the host (toolkit/verify/bsdf_check.py, tests/test_bsdf.py) can check that
 * each material samples the density its own eval reports. Everything is in the local frame
 * (normal +z). Build with every HAS_* define set to 1 and the MAT_* codes of toolkit.core.scene. */
#include "materials.h"
#include "philox.h"

/* One sample per work-item; the random numbers are Philox block 0 of (seed, gid, 0).
 * wi_pdf: xyz = wi, w = pdf (0 for a specular choice, -1 when the sample failed);
 * weight: xyz = weight, w = 1 for a specular choice, else 0 (all zero when the sample failed). */
__kernel void bsdf_test_sample(const Material m, const float4 wo, const uint seed, const int n,
                               __global float4* wi_pdf, __global float4* weight)
{
    int gid = get_global_id(0);
    if (gid >= n) return;
    float4 u = rng_block(seed, (uint)gid, 0u, 0u);
    BsdfSample s;
    s.wi = (float3)(0.0f);
    s.weight = (float3)(0.0f);
    bool ok = bsdf_sample(&m, wo.xyz, u.x, u.y, u.z, &s);
    if (ok) {
        wi_pdf[gid] = (float4)(s.wi, s.pdf);
        weight[gid] = (float4)(s.weight, s.specular ? 1.0f : 0.0f);
    } else {
        wi_pdf[gid] = (float4)(0.0f, 0.0f, 0.0f, -1.0f);
        weight[gid] = (float4)(0.0f);
    }
}

/* f(wo, wi[gid]) (without the cosine) in xyz and the solid-angle pdf of sampling wi in w. */
__kernel void bsdf_test_eval(const Material m, const float4 wo, const int n,
                             __global const float4* wi, __global float4* f_pdf)
{
    int gid = get_global_id(0);
    if (gid >= n) return;
    float pdf;
    float3 f = bsdf_eval(&m, wo.xyz, wi[gid].xyz, &pdf);
    f_pdf[gid] = (float4)(f, pdf);
}
