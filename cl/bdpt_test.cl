/* Test kernel: the MIS weights of every strategy that can make one given path.
 * `path` holds n vertices in light-to-eye order: path[0] lies on a light (front side),
 * path[n - 1] is the camera. Work-item s splits it into s light and n - s eye vertices,
 * fills in the densities the random walk would have stored, and evaluates the strategy
 * with the same connect_strategy() the renderers use. The weights must sum to one. */
#include "bdpt.h"

__kernel void bdpt_test_mis_splits(SCENE_PARAMS, const Camera cam, const int n,
                                   __global const BdptVertex* path,
                                   __global BdptVertex* light_scratch, __global BdptVertex* eye_scratch,
                                   __global float* weights)
{
    int s_len = get_global_id(0);
    if (s_len >= n) return;
    int t_len = n - s_len;
    SceneView s = SCENE_INIT;
    __global BdptVertex* L = light_scratch + s_len * MAX_VERTICES;
    __global BdptVertex* E = eye_scratch + s_len * MAX_VERTICES;
    for (int i = 0; i < s_len; ++i) L[i] = path[i];
    for (int j = 0; j < t_len; ++j) E[j] = path[n - 1 - j];
    if (s_len > 0) L[0].flags = VERTEX_LIGHT;
    /* Directions to the previous vertex of each subpath. */
    for (int i = 1; i < s_len; ++i) L[i].wo = (float4)(normalize(L[i - 1].pos.xyz - L[i].pos.xyz), 0.0f);
    for (int j = 1; j < t_len; ++j) E[j].wo = (float4)(normalize(E[j - 1].pos.xyz - E[j].pos.xyz), 0.0f);
    /* pdf_fwd and pdf_rev as the walk stores them. */
    for (int i = 0; i < s_len; ++i) {
        BdptVertex v = L[i];
        if (i == 0) {
            v.pdf_fwd = light_origin_pdf(&s, &v);
        } else {
            BdptVertex a = L[i - 1], b = L[max(i - 2, 0)];
            v.pdf_fwd = vertex_pdf(&s, &cam, i >= 2 ? &b : 0, &a, &v);
        }
        v.pdf_rev = 0.0f;
        if (i >= 1 && i + 1 < s_len) {
            BdptVertex next = L[i + 1], prev = L[i - 1];
            v.pdf_rev = vertex_pdf(&s, &cam, &next, &v, &prev);
        }
        L[i] = v;
    }
    for (int j = 0; j < t_len; ++j) {
        BdptVertex v = E[j];
        if (j == 0) {
            v.pdf_fwd = 1.0f;
        } else {
            BdptVertex a = E[j - 1], b = E[max(j - 2, 0)];
            v.pdf_fwd = vertex_pdf(&s, &cam, j >= 2 ? &b : 0, &a, &v);
        }
        v.pdf_rev = 0.0f;
        if (j >= 2 && j + 1 < t_len) {
            BdptVertex next = E[j + 1], prev = E[j - 1];
            v.pdf_rev = vertex_pdf(&s, &cam, &next, &v, &prev);
        }
        E[j] = v;
    }
    int steps = 0;
    Connection c = connect_strategy(&s, &cam, E, L, s_len, t_len, 0, &steps);
    weights[s_len] = c.pixel >= 0 ? c.weight : 0.0f;
}
