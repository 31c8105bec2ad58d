/* Grader kernel of assignment 3 (toolkit/grading/checks/parallel_connect.py): the student's find_sample() for every
 * connection g of a given exclusive scan `firsts` of n connection counts. */
#include "bdpt_parallel_connect.cl"

__kernel void grade_find_sample(__global const int* firsts, const int n, const int total, __global int* found)
{
    int g = get_global_id(0);
    if (g >= total) return;
    found[g] = find_sample(firsts, n, g);
}
