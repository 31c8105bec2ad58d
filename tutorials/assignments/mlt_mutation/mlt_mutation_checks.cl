/* Grader kernel of assignment 6 (toolkit/grading/checks/mlt_mutation.py): the student's
 * mlt_perturb() on known inputs, out[k] = mlt_perturb(u[k], r[k]). */
#include "mlt_mutation.h"

__kernel void grade_mlt_perturb(__global const float* u, __global const float* r, const int n, __global float* out)
{
    int k = get_global_id(0);
    if (k >= n) return;
    out[k] = mlt_perturb(u[k], r[k]);
}
