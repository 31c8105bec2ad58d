/* MIS weight of one BDPT strategy (s, t) among all the strategies that could have made the
 * same path (Veach's thesis sec. 10.3.4, pbrt-v3 sec. 16.3.4 "Multiple importance sampling").
 * Included by bdpt.h; compiles on its own (BdptVertex and VERTEX_DELTA come with layout.h,
 * remap0() with bdpt_vertex.h). It is the file that course assignment 4
 * (tutorials/assignments/mis/) replaces with a student's own.
 *
 * With p_i the area density of the path under strategy i (i = s light vertices) and p_s that
 * of the strategy evaluated, the ratios r_i = p_i / p_s follow from the stored densities, one
 * vertex at a time, walking each subpath backwards from the connection:
 *     r_{s-1} = pdf_rev(y_{s-1}) / pdf_fwd(y_{s-1}),   r_{i-1} = r_i * pdf_rev(y_{i-1}) / pdf_fwd(y_{i-1})
 * (and the same along the eye subpath for r_{s+1}, r_{s+2}, ...). Strategies that would connect at
 * a delta (specular) vertex cannot make the path and are left out of the sum.
 *   balance heuristic (Veach eq. 9.5):          w_s = p_s / sum_i p_i       = 1 / (1 + sum r_i)
 *   power heuristic, beta = 2 (Veach eq. 9.13): w_s = p_s^2 / sum_i p_i^2   = 1 / (1 + sum r_i^2)
 * The renderers use the balance heuristic; -DMIS_POWER=1 selects the power heuristic. */
#ifndef MIS_H
#define MIS_H

#include "common.h"
#include "bdpt_vertex.h"

#ifndef MIS_POWER
#define MIS_POWER 0
#endif

typedef struct {
    float pt_rev, ptm_rev, qs_rev, qsm_rev;   /* recomputed reverse densities at the connection */
} ConnectionPdfs;

/* The term a strategy with density ratio r (to the evaluated one) adds to the denominator. */
HELPER float mis_term(float r) { return MIS_POWER ? r * r : r; }

HELPER float mis_weight(__global const BdptVertex* eye, __global const BdptVertex* light,
                        int s, int t, const ConnectionPdfs* c) {
    float sum = 0.0f;
    /* Hypothetical strategies with more light vertices: walk the eye subpath backwards. */
    float r = 1.0f;
    for (int i = t - 1; i > 0; --i) {
        float rev = i == t - 1 ? c->pt_rev : i == t - 2 ? c->ptm_rev : eye[i + 1].pdf_rev;
        r *= remap0(rev) / remap0(eye[i].pdf_fwd);
        bool delta_i = i == t - 1 ? false : (eye[i].flags & VERTEX_DELTA) != 0;
        bool delta_prev = i - 1 == t - 1 ? false : (eye[i - 1].flags & VERTEX_DELTA) != 0;
        if (!delta_i && !delta_prev) sum += mis_term(r);
    }
    /* Hypothetical strategies with more eye vertices: walk the light subpath backwards. */
    r = 1.0f;
    for (int i = s - 1; i >= 0; --i) {
        float rev = i == s - 1 ? c->qs_rev : i == s - 2 ? c->qsm_rev : light[i + 1].pdf_rev;
        r *= remap0(rev) / remap0(light[i].pdf_fwd);
        bool delta_i = i == s - 1 ? false : (light[i].flags & VERTEX_DELTA) != 0;
        bool delta_prev = i > 0 ? (light[i - 1].flags & VERTEX_DELTA) != 0 : false;  /* area lights are not delta */
        if (!delta_i && !delta_prev) sum += mis_term(r);
    }
    return 1.0f / (1.0f + sum);
}

#endif
