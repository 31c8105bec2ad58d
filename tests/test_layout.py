"""Host and device agree on every generated layout, and kernels stay short enough to read."""
import numpy as np
import pyopencl as cl
import pytest

from toolkit.core import layout

from toolkit.opencl import program
from toolkit.techniques import TECHNIQUES


def test_every_generated_struct_has_numpys_sizeof_and_offsetof_on_the_device(queue):
    built = program.build(queue.context, "layout_check.cl")
    checks = layout.layout_checks()
    out = np.full(len(checks), -1, np.int32)
    buffer = cl.Buffer(queue.context, cl.mem_flags.WRITE_ONLY, out.nbytes)
    program.kernel(built, "layout_check")(queue, (1,), None, buffer)
    cl.enqueue_copy(queue, out, buffer)
    wrong = [f"{what}: device {got}, numpy {want}" for (what, _, want), got in zip(checks, out) if got != want]
    assert not wrong, wrong
    assert len(checks) > 2 * len(layout.RECORDS)


def test_float4_fields_are_16_byte_aligned_like_c():
    record = layout.Record("Probe", [("a", "int"), ("b", "float4")])
    assert record.dtype.fields["b"][1] == 16 and record.dtype.itemsize == 32


@pytest.mark.parametrize("name", sorted(TECHNIQUES))
def test_no_kernel_takes_more_than_16_arguments(queue, cornell_spheres, name):
    from toolkit.opencl.device_scene import DeviceScene
    tech = TECHNIQUES[name](queue, DeviceScene(queue, cornell_spheres))
    counts = {k.function_name: k.num_args for k in tech.program.all_kernels()}
    assert counts and max(counts.values()) <= 16, counts


def test_named_w_lanes_are_the_fourth_float_of_their_field_on_both_sides(queue, tmp_path):
    from toolkit.core.record_lanes import lane_dtype
    (tmp_path / "lanes.cl").write_text('#include "common.h"\n__kernel void lanes(__global Subpath* out) {\n'
                                       '    Subpath p = {.origin = (float4)(0.0f), .beta = (float4)(0.0f)};\n'
                                       '    SUBPATH_PDF_DIR(&p) = 2.5f;\n    SUBPATH_RR_NORMALISER(&p) = 7.0f;\n'
                                       '    out[0] = p;\n}\n')
    built = program.build(queue.context, "lanes.cl", directory=tmp_path)
    out = np.zeros(1, lane_dtype(layout.SUBPATH, layout.SUBPATH_LANES))
    assert out.dtype.itemsize == layout.SUBPATH.dtype.itemsize
    buffer = cl.Buffer(queue.context, cl.mem_flags.WRITE_ONLY, out.nbytes)
    program.kernel(built, "lanes")(queue, (1,), None, buffer)
    cl.enqueue_copy(queue, out, buffer)
    assert out["pdf_dir"][0] == out["origin"][0, 3] == 2.5
    assert out["rr_normaliser"][0] == out["beta"][0, 3] == 7.0
