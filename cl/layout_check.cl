/* Test kernel: sizeof and offsetof of every struct generated from toolkit/core/layout.py, as the
 * device compiler lays them out; tests/test_layout.py compares them with the numpy dtypes. */
#include "common.h"

__kernel void layout_check(__global int* out)
{
    if (get_global_id(0) == 0) LAYOUT_CHECKS(out);
}
