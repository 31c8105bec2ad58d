/* Assignment 4: MIS weights for BDPT (van Antwerpen, HPG 2011, slide "Bidirectional Path
 * Tracing": all (s, t) strategies of a sample, combined by multiple importance sampling).
 * Your file replaces the toolkit's cl/mis.h (included by cl/bdpt.h):
 *     python -m toolkit grade mis --kernel THIS_FILE
 * Fill in the region marked TODO; keep the names of ConnectionPdfs and mis_weight.
 *
 * Strategy (s, t) joins s light vertices y_0..y_{s-1} (y_0 on the light) and t eye vertices
 * z_0..z_{t-1} (z_0 the camera). Every stored vertex v has
 *   v.pdf_fwd  the area density with which its own subpath generated it,
 *   v.pdf_rev  the area density of generating the PREVIOUS vertex of its subpath from v,
 *              in the reverse direction (so the reverse density of vertex i is read from vertex i + 1),
 *   v.flags    VERTEX_DELTA for a specular vertex.
 * At the connection, the four densities that change are recomputed and passed in `c`:
 *   c->pt_rev  reverse density of z_{t-1},   c->ptm_rev  of z_{t-2},
 *   c->qs_rev  reverse density of y_{s-1},   c->qsm_rev  of y_{s-2}.
 * With p_i the density of the path under strategy i and p_s the evaluated one, the ratios
 * r_i = p_i / p_s follow one vertex at a time, walking each subpath backwards from its end:
 *   eye side   (i = t-1 down to 1):  r *= rev(z_i) / pdf_fwd(z_i)   (strategies with more light vertices)
 *   light side (i = s-1 down to 0):  r *= rev(y_i) / pdf_fwd(y_i)   (strategies with more eye vertices)
 * where rev() is the recomputed density for the last two vertices and the stored pdf_rev of
 * the next vertex otherwise. Pass every density through remap0() (0 -> 1), as pbrt-v3 does.
 * A strategy that would connect at a delta vertex cannot make the path: leave its r_i out of
 * the sum (on the eye side: z_i or z_{i-1} delta, except that the connection vertices
 * themselves are never delta; on the light side: y_i or y_{i-1} delta, the light is not).
 *   balance heuristic:           w_s = 1 / (1 + sum_i r_i)
 *   power heuristic (beta = 2):  w_s = 1 / (1 + sum_i r_i^2)     when MIS_POWER is 1 */
#ifndef MIS_H
#define MIS_H

#ifndef MIS_POWER
#define MIS_POWER 0
#endif

typedef struct {
    float pt_rev, ptm_rev, qs_rev, qsm_rev;   /* recomputed reverse densities at the connection */
} ConnectionPdfs;

static inline float mis_weight(__global const BdptVertex* eye, __global const BdptVertex* light,
                        int s, int t, const ConnectionPdfs* c) {
    /* TODO: the sums of the ratios along both subpaths; then the balance or power heuristic. */
    (void)eye; (void)light; (void)s; (void)t; (void)c;
    return 0.0f;
}

#endif
