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
