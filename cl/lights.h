/* One-sided triangle area lights and next-event estimation.
 * A light triangle is picked in proportion to its power (area x luminance of emission),
 * then a point uniformly on it; the host stores, per triangle, the resulting density per
 * unit area (Triangle.light_pdf) so a BSDF-sampled hit can be MIS-weighted too. */
#ifndef LIGHTS_H
#define LIGHTS_H

#include "scene.h"

typedef struct {
    float3 p;         /* point on the light */
    float3 n;         /* its normal (the emitting side) */
    float3 emission;
    float pdf_area;   /* density per unit area of choosing p */
    int light;        /* index into the light array */
} LightSample;

HELPER int pick_light(const SceneView* scene, float u) {
    int lo = 0, hi = scene->light_count - 1;
    while (lo < hi) {               /* first light whose inclusive CDF exceeds u */
        int mid = (lo + hi) / 2;
        if (scene->lights[mid].cdf > u) hi = mid; else lo = mid + 1;
    }
    return lo;
}

HELPER LightSample sample_light(const SceneView* scene, float u_pick, float u1, float u2) {
    int index = pick_light(scene, u_pick);
    LightTri light = scene->lights[index];
    Triangle tri = scene->tris[light.triangle];
    float r = sqrt(u1);              /* uniform on the triangle (Shirley's square-root map) */
    float b1 = u2 * r, b2 = 1.0f - r;
    LightSample ls;
    ls.p = tri.v0.xyz + b1 * (tri.v1.xyz - tri.v0.xyz) + b2 * (tri.v2.xyz - tri.v0.xyz);
    ls.n = triangle_normal(&tri);
    ls.emission = light.emission.xyz;
    ls.pdf_area = tri.light_pdf;
    ls.light = index;
    return ls;
}

/* Radiance leaving triangle `tri` (normal n) towards w, pointing away from it: lights are one-sided. */
HELPER float3 emitted(const SceneView* scene, const Triangle* tri, float3 n, float3 w) {
    if (tri->light < 0 || dot(n, w) <= 0.0f) return (float3)(0.0f);
    return scene->lights[tri->light].emission.xyz;
}

#endif
