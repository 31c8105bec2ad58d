/* Test kernel: the MIS weights of every strategy that can make one given path.
 * `path` holds n vertices in light-to-eye order: path[0] lies on a light (front side),
 * path[n - 1] is the camera. Work-item s splits it into s light and n - s eye vertices,
 * fills in the densities the random walk would have stored, and evaluates the strategy
 * with the same connect_strategy() the renderers use. The weights must sum to one. */
#include "bdpt.h"

/* The densities the random walk (cl/bdpt_walk.h) stores on the vertices v[0..len) of one
 * subpath: pdf_fwd of each vertex from the two before it (of the origin: the light's area
 * density, or 1 for the pinhole), and pdf_rev from the next vertex, for the vertices that have
 * both neighbours, except z_1, whose previous vertex is the pinhole (a delta in position). */
HELPER void store_walk_densities(const SceneView* scene, const Camera* cam, __global BdptVertex* v, int len, int is_light)
{
    for (int i = 0; i < len; ++i) {
        BdptVertex x = v[i];
        if (i == 0) {
            x.pdf_fwd = is_light ? light_origin_pdf(scene, &x) : 1.0f;
        } else {
            BdptVertex a = v[i - 1], b = v[max(i - 2, 0)];
            x.pdf_fwd = vertex_pdf(scene, cam, i >= 2 ? &b : 0, &a, &x);
        }
        x.pdf_rev = 0.0f;
        if (i >= (is_light ? 1 : 2) && i + 1 < len) {
            BdptVertex next = v[i + 1], prev = v[i - 1];
            x.pdf_rev = vertex_pdf(scene, cam, &next, &x, &prev);
        }
        v[i] = x;
    }
}

__kernel void bdpt_test_mis_splits(SCENE_PARAMS, const Camera cam, const int n,
                                   __global const BdptVertex* path,
                                   __global BdptVertex* light_scratch, __global BdptVertex* eye_scratch,
                                   __global float* weights)
{
    int s_len = get_global_id(0);
    if (s_len >= n) return;
    int t_len = n - s_len;
    SceneView scene = SCENE_INIT;
    __global BdptVertex* L = light_scratch + s_len * MAX_VERTICES;
    __global BdptVertex* E = eye_scratch + s_len * MAX_VERTICES;
    for (int i = 0; i < s_len; ++i) L[i] = path[i];
    for (int j = 0; j < t_len; ++j) E[j] = path[n - 1 - j];
    if (s_len > 0) L[0].flags = VERTEX_LIGHT;
    /* Directions to the previous vertex of each subpath. */
    for (int i = 1; i < s_len; ++i) L[i].wo = (float4)(normalize(L[i - 1].pos.xyz - L[i].pos.xyz), 0.0f);
    for (int j = 1; j < t_len; ++j) E[j].wo = (float4)(normalize(E[j - 1].pos.xyz - E[j].pos.xyz), 0.0f);
    /* pdf_fwd and pdf_rev as the walk stores them. */
    store_walk_densities(&scene, &cam, L, s_len, 1);
    store_walk_densities(&scene, &cam, E, t_len, 0);
    int steps = 0;
    Connection c = connect_strategy(&scene, &cam, E, L, s_len, t_len, 0, &steps);
    weights[s_len] = c.pixel >= 0 ? c.weight : 0.0f;
}
