/* Plain path tracing: one path per work-item, traced from the camera to termination.
 * A work-item whose path has ended idles until the longest path in its warp is done:
 * this is the baseline of the talk ("Random Walk": ~33% active threads per warp).
 * Kernels this technique launches (toolkit/techniques/pt_naive.py):
 *   pt_naive_render   here */
#include "path.h"

/* `pass_args`: the pass's seed, sample_base and budget (one work-item per sample; PtPass, layout.h). */
__kernel void pt_naive_render(SCENE_PARAMS, const Camera cam, const PtPass pass_args,
                              __global float4* radiance,          /* one per work-item; .w = 1: non-finite */
                              __global LaneCounts* lane_counts)   /* per lane: .work = loop iterations */
{
    int gid = get_global_id(0);
    if (gid >= pass_args.budget) return;
    SceneView scene = SCENE_INIT;
    uint seed = pass_args.seed;
    PathState path;
    path_start_sample(&path, &cam, gid, pass_args.sample_base, seed);
    LaneCounters count = {0, 0, 0};
    int iterations = 0;
#if !(USE_MAX_DEPTH) || MAX_DEPTH > 0
    bool alive = true;
    while (alive) {
        alive = path_extend(&scene, &path, seed, &count);
        ++iterations;
    }
#endif
    path_finish(radiance, &path);
#if COUNT_SIMD
    lane_counts[gid] = lane_counts_of(iterations, &count);
#endif
}
