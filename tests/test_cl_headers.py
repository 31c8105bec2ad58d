"""Headers of cl/ that a kernel (or a student's replacement) includes by themselves compile alone.

cl/mis.h is the file course assignment 4 replaces (toolkit/grading/grade.py builds a student's
mis.h in its place), so it must not depend on what bdpt.h happens to define before including it."""
import numpy as np
import pyopencl as cl
import pytest

from toolkit.core.layout import BDPT_VERTEX, VertexFlag
from toolkit.opencl import program

# A kernel that includes mis.h and nothing else: strategy (s, t) = (1, 2) of a path y_0 z_1 z_0.
MIS_ALONE = """#include "mis.h"
__kernel void mis_alone(__global const BdptVertex* eye, __global const BdptVertex* light, __global float* out) {
    ConnectionPdfs c = {.pt_rev = 2.0f, .ptm_rev = 0.0f, .qs_rev = 4.0f, .qsm_rev = 0.0f};
    out[0] = mis_weight(eye, light, 1, 2, &c);
}
"""


@pytest.mark.parametrize("power, weight", [(False, 0.5), (True, 2.0 / 3.0)])
def test_mis_h_compiles_alone_and_weighs_the_other_two_strategies(queue, tmp_path, power, weight):
    (tmp_path / "mis_alone.cl").write_text(MIS_ALONE)
    built = program.build(queue, "mis_alone.cl", {"MIS_POWER": power}, directory=tmp_path)
    eye, light = BDPT_VERTEX.zeros(2), BDPT_VERTEX.zeros(1)
    eye["flags"][0] = VertexFlag.CAMERA
    eye["pdf_fwd"] = [1.0, 4.0]      # ratio of strategy (2, 1): pt_rev / pdf_fwd(z_1) = 2 / 4
    light["pdf_fwd"] = [8.0]         # ratio of strategy (0, 3): qs_rev / pdf_fwd(y_0) = 4 / 8
    mf = cl.mem_flags
    eye_buffer = cl.Buffer(queue.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=eye)
    light_buffer = cl.Buffer(queue.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=light)
    out = np.zeros(1, np.float32)
    out_buffer = cl.Buffer(queue.context, mf.WRITE_ONLY, out.nbytes)
    program.kernel(built, "mis_alone")(queue, (1,), None, eye_buffer, light_buffer, out_buffer)
    cl.enqueue_copy(queue, out, out_buffer)
    # balance: 1 / (1 + 1/2 + 1/2); power: 1 / (1 + 1/4 + 1/4)
    assert out[0] == pytest.approx(weight, rel=1e-6)
