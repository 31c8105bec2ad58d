/* Test kernel: the 64-bit index path of the vertex memory (cl/vertex_memory.h) at vertex
 * indices whose word offsets pass 2^31, without allocating gigabytes: work-item i writes
 * vertex_word(index[i], w[i]) as two 32-bit halves. tests/test_work_sizes.py checks them. */
#include "vertex_memory.h"

__kernel void vertex_word_test(const int n, __global const int* index, __global const int* w, __global uint* out)
{
    int gid = get_global_id(0);
    if (gid >= n) return;
    ulong word = (ulong)vertex_word(index[gid], w[gid]);
    out[2 * gid] = (uint)(word & 0xffffffffu);
    out[2 * gid + 1] = (uint)(word >> 32);
}
