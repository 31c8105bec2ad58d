/* Grader kernel of assignment 4 (toolkit/grading/checks/mis.py): the student's mis_weight() on
 * known densities. Case k has its eye and light subpaths at eye + k * stride, light + k * stride,
 * its strategy (s, t) in st[k] and the four recomputed densities in pdfs[k]. */
#include "common.h"
#include "bdpt_vertex.h"
#include "mis.h"

__kernel void grade_mis_known(__global const BdptVertex* eye, __global const BdptVertex* light,
                              __global const int2* st, __global const float4* pdfs, const int stride,
                              const int n, __global float* weights)
{
    int k = get_global_id(0);
    if (k >= n) return;
    ConnectionPdfs c = {pdfs[k].x, pdfs[k].y, pdfs[k].z, pdfs[k].w};
    weights[k] = mis_weight(eye + k * stride, light + k * stride, st[k].x, st[k].y, &c);
}
