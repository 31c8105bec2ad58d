/* The device probe (toolkit/opencl/device.py): a small kernel that uses what the toolkit's kernels
 * use (the generated layout header, pyopencl's Philox, float3 maths, local memory with
 * barriers, global atomics), built once per device to find out whether this OpenCL
 * implementation can build and run them. The host checks every number it writes. */
#include "common.h"
#include "philox.h"

__kernel void probe(__global float* lengths, __global int* group_sums, volatile __global int* counter) {
    __local int scratch[LOCAL_SIZE];
    int gid = get_global_id(0), lid = get_local_id(0);

    /* Random numbers and a cosine-weighted direction in a basis: the vector must be unit length. */
    Sampler sampler = sampler_init(7u, (uint)gid, 0u);
    float3 local_dir = sample_cosine_hemisphere(sampler_get(&sampler, 0), sampler_get(&sampler, 1));
    float3 s, t, n = normalize((float3)(1.0f, 2.0f, 3.0f));
    make_basis(n, &s, &t);
    lengths[gid] = length(to_world(local_dir, s, t, n));

    /* A work-group sum through local memory: gid values, summed by the first lane. */
    scratch[lid] = gid;
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid == 0) {
        int sum = 0;
        for (int i = 0; i < LOCAL_SIZE; ++i) sum += scratch[i];
        group_sums[get_group_id(0)] = sum;
    }
    atomic_inc(counter);
}
