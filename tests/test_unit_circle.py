"""cl/common.h unit_circle: (cos, sin) of 2 pi u without the library's sin and cos (a quadrant
and two short Taylor series), checked against numpy's float64 values over a fine grid of u."""
import numpy as np
import pyopencl as cl

from toolkit.opencl import program

KERNEL = """
#include "common.h"
__kernel void circle(__global const float* u, __global float2* out, const int n)
{
    int i = get_global_id(0);
    if (i < n) out[i] = unit_circle(u[i]);
}
"""


def test_unit_circle_matches_cos_and_sin_to_float_rounding(queue, tmp_path):
    (tmp_path / "circle.cl").write_text(KERNEL)
    built = program.build(queue, "circle.cl", directory=tmp_path)
    # every quadrant boundary and its neighbours, and 2^20 evenly spaced values
    u = np.concatenate([np.linspace(0, 1, 1 << 20, endpoint=False), [0.25, 0.5, 0.75],
                        np.nextafter(np.float32([0.25, 0.5, 0.75, 1.0]), np.float32(0)),
                        np.nextafter(np.float32([0.0, 0.25, 0.5, 0.75]), np.float32(1))]).astype(np.float32)
    out = np.empty((len(u), 2), np.float32)
    flags = cl.mem_flags
    u_buf = cl.Buffer(queue.context, flags.READ_ONLY | flags.COPY_HOST_PTR, hostbuf=u)
    out_buf = cl.Buffer(queue.context, flags.WRITE_ONLY, out.nbytes)
    program.launch(queue, program.kernel(built, "circle"), len(u), u_buf, out_buf, np.int32(len(u)))
    cl.enqueue_copy(queue, out, out_buf)
    angle = 2 * np.pi * u.astype(np.float64)
    # float32 rounding of the angle's parts and of ~15 operations: measured 1.4e-7 at most, about
    # one ulp of 1 (1.2e-7); 3e-7 allows two and a half
    assert np.abs(out[:, 0] - np.cos(angle)).max() < 3e-7
    assert np.abs(out[:, 1] - np.sin(angle)).max() < 3e-7
    assert np.abs(np.hypot(out[:, 0], out[:, 1]) - 1).max() < 3e-7
