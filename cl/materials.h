/* The materials of scenes/FORMAT.md, in a local frame where the surface normal is +z.
 * Each block is compiled only when the scene uses that material (HAS_* defines).
 *
 * bsdf_eval   returns f(wo, wi) (without the cosine) and the solid-angle pdf of sampling wi;
 * bsdf_sample draws wi and returns the weight f |cos| / pdf.
 * wo points away from the surface (towards the previous vertex). */
#ifndef MATERIALS_H
#define MATERIALS_H

#include "common.h"

typedef struct {
    float3 wi;        /* sampled direction, local frame */
    float3 weight;    /* f |cos theta_i| / pdf; for specular lobes the discrete weight */
    float pdf;        /* solid-angle pdf; 0 for a specular (delta) choice */
    bool specular;
} BsdfSample;

/* Materials whose every lobe is a delta distribution: no light sampling, no evaluation. */
HELPER bool is_specular(int type) {
    return false
#if HAS_MIRROR
        || type == MAT_MIRROR
#endif
#if HAS_DIELECTRIC
        || type == MAT_DIELECTRIC
#endif
        ;
}

/* The shading normal at a surface with geometric normal ng, seen from direction wo:
 * two-sided materials shade with the normal facing wo; a dielectric keeps its outward
 * normal (its BSDF tells inside from outside by the sign of wo.z). */
HELPER float3 shading_normal(int type, float3 ng, float3 wo) {
#if HAS_DIELECTRIC
    if (type == MAT_DIELECTRIC) return ng;
#endif
    return dot(ng, wo) < 0.0f ? -ng : ng;
}


#if HAS_GLOSSY
/* GGX (Trowbridge-Reitz) as FORMAT.md defines it; Walter et al. 2007, eqs. 33-34. */
HELPER float ggx_d(float3 m, float alpha) {
    if (m.z <= 0.0f) return 0.0f;
    float a2 = alpha * alpha;
    /* k = cos^2 (a2 - 1) + 1 written as sin^2 + cos^2 a2: the textbook form cancels to 0 in
     * float32 for a2 below 6e-8 (alpha ~ 2.4e-4) at m = n, and D became infinite. */
    float k = (m.x * m.x + m.y * m.y) + m.z * m.z * a2;
    return a2 / (PI * k * k);
}
HELPER float ggx_g1(float3 w, float alpha) {
    float c2 = w.z * w.z;
    if (c2 <= 0.0f) return 0.0f;
    float tan2 = fmax(0.0f, 1.0f - c2) / c2;
    return 2.0f / (1.0f + sqrt(1.0f + alpha * alpha * tan2));
}
/* Visible-normal sampling: Heitz 2018, "Sampling the GGX Distribution of Visible Normals". */
HELPER float3 ggx_sample_visible_normal(float3 wo, float alpha, float u1, float u2) {
    float3 vh = normalize((float3)(alpha * wo.x, alpha * wo.y, wo.z));
    float len2 = vh.x * vh.x + vh.y * vh.y;
    float3 t1 = len2 > 0.0f ? (float3)(-vh.y, vh.x, 0.0f) * rsqrt(len2) : (float3)(1.0f, 0.0f, 0.0f);
    float3 t2 = cross(vh, t1);
    float r = sqrt(u1);
    float2 circle = unit_circle(u2);
    float p1 = r * circle.x, p2 = r * circle.y;
    float s = 0.5f * (1.0f + vh.z);
    p2 = (1.0f - s) * sqrt(fmax(0.0f, 1.0f - p1 * p1)) + s * p2;
    float3 nh = p1 * t1 + p2 * t2 + sqrt(fmax(0.0f, 1.0f - p1 * p1 - p2 * p2)) * vh;
    return normalize((float3)(alpha * nh.x, alpha * nh.y, fmax(1e-6f, nh.z)));
}
/* pdf of wi under visible-normal sampling: G1(wo) D(m) / (4 cos theta_o). */
HELPER float ggx_pdf(float3 wo, float3 wi, float alpha) {
    if (wo.z <= 0.0f || wi.z <= 0.0f) return 0.0f;
    float3 m = normalize(wo + wi);
    return ggx_g1(wo, alpha) * ggx_d(m, alpha) / (4.0f * wo.z);
}
#endif

#if HAS_DIELECTRIC
/* Unpolarised Fresnel reflectance for relative index eta = n_t / n_i; cos_t returned (>= 0). */
HELPER float fresnel_dielectric(float cos_i, float eta, float* cos_t) {
    float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0f) { *cos_t = 0.0f; return 1.0f; }  /* total internal reflection */
    float ct = sqrt(1.0f - sin2_t);
    float rs = (cos_i - eta * ct) / (cos_i + eta * ct);
    float rp = (eta * cos_i - ct) / (eta * cos_i + ct);
    *cos_t = ct;
    return 0.5f * (rs * rs + rp * rp);
}
#endif

/* f(wo, wi) and the pdf of sampling wi; zero for delta lobes (they are never evaluated). */
HELPER float3 bsdf_eval(const Material* m, float3 wo, float3 wi, float* pdf) {
    *pdf = 0.0f;
    if (wo.z <= 0.0f || wi.z <= 0.0f) return (float3)(0.0f);
#if HAS_DIFFUSE
    if (m->type == MAT_DIFFUSE) {
        *pdf = wi.z * INV_PI;
        return m->reflectance.xyz * INV_PI;
    }
#endif
#if HAS_GLOSSY
    if (m->type == MAT_GLOSSY) {
        float3 h = normalize(wo + wi);
        float a = m->alpha;
        *pdf = ggx_pdf(wo, wi, a);
        return m->reflectance.xyz * (ggx_d(h, a) * ggx_g1(wo, a) * ggx_g1(wi, a) / (4.0f * wo.z * wi.z));
    }
#endif
    return (float3)(0.0f);
}

/* Draw wi given wo. The two-sided materials expect wo.z > 0 (the caller flips the frame);
 * the dielectric takes wo on either side: +z is its exterior (index 1). Returns false when
 * the path ends (no valid direction). */
HELPER bool bsdf_sample(const Material* m, float3 wo, float u1, float u2, float u_lobe, BsdfSample* out) {
    out->specular = false;
    out->pdf = 0.0f;
#if HAS_DIFFUSE
    if (m->type == MAT_DIFFUSE) {
        if (wo.z <= 0.0f) return false;
        out->wi = sample_cosine_hemisphere(u1, u2);
        out->pdf = out->wi.z * INV_PI;
        out->weight = m->reflectance.xyz;  /* (R / pi) cos / (cos / pi) */
        return out->pdf > 0.0f;
    }
#endif
#if HAS_MIRROR
    if (m->type == MAT_MIRROR) {
        if (wo.z <= 0.0f) return false;
        out->wi = (float3)(-wo.x, -wo.y, wo.z);
        out->weight = m->reflectance.xyz;
        out->specular = true;
        return true;
    }
#endif
#if HAS_GLOSSY
    if (m->type == MAT_GLOSSY) {
        if (wo.z <= 0.0f) return false;
        float3 mn = ggx_sample_visible_normal(wo, m->alpha, u1, u2);
        float3 wi = 2.0f * dot(wo, mn) * mn - wo;
        if (wi.z <= 0.0f) return false;  /* reflected below the horizon: energy lost (F = 1 conductor) */
        out->wi = wi;
        out->pdf = ggx_pdf(wo, wi, m->alpha);
        out->weight = m->reflectance.xyz * ggx_g1(wi, m->alpha);  /* f cos / pdf simplifies to R G1(wi) */
        return out->pdf > 0.0f;
    }
#endif
#if HAS_DIELECTRIC
    if (m->type == MAT_DIELECTRIC) {
        bool entering = wo.z > 0.0f;
        float eta = entering ? m->ior : 1.0f / m->ior;   /* n_t / n_i */
        float cos_i = fabs(wo.z), cos_t;
        float F = fresnel_dielectric(cos_i, eta, &cos_t);
        out->specular = true;
        out->weight = (float3)(1.0f);  /* choosing reflect/refract with probability F cancels F */
        if (u_lobe < F) {
            out->wi = (float3)(-wo.x, -wo.y, wo.z);
        } else {
            /* Snell: the tangential part scales by 1/eta, the normal part flips side.
             * The (eta)^2 radiance scaling is omitted: it cancels along every path (FORMAT.md). */
            float3 wt = -wo / eta;
            wt.z = entering ? -cos_t : cos_t;
            out->wi = normalize(wt);
        }
        return true;
    }
#endif
    return false;
}

#endif
