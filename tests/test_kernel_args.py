"""Kernel launches read by name (issue 23): the host passes a kernel's arguments under the
kernel's own parameter names, in its order (Kernels.launch(kernel, n, **named)), and the
compiler keeps those names when asked (-cl-kernel-arg-info: program.build(arg_info=True)), so
this test renders a small image with each technique and checks every launch before it runs.
(A parameter named like an OpenCL builtin, `length` or `step`, comes back renamed on PoCL, `_cl_length`:
the kernels avoid such names.)

Every technique passes every argument by name, and each value's kind (a buffer, an int, a uint,
a float or a layout.py record) must be the type of the parameter in its place. Every kernel in a
technique's program must be launched by one of its variants, so none goes unchecked."""
from pathlib import Path

import numpy as np
import pyopencl as cl
import pytest

from toolkit.core.layout import RECORDS
from toolkit.opencl import program
from toolkit.opencl.device_scene import DeviceScene
from toolkit.techniques import get_technique
from toolkit.techniques.kernels import Kernels

ROOT = Path(__file__).resolve().parent.parent

# Each technique's program (its cl/ file) and the variants that, together, launch every kernel in it.
PROGRAMS = {
    "pt_naive.cl": ["pt_naive"],
    "pt_inplace_regen.cl": ["pt_inplace_regen"],
    "pt_compact_regen.cl": ["pt_compact_regen", "pt_compact_regen/multipass"],
    "bdpt_naive_connect.cl": ["bdpt_naive_connect"],
    "bdpt_parallel_connect.cl": ["bdpt_parallel_connect"],
    # pool: the start from chosen candidates (mlt_start_from); resample: the chains' weights (mlt_resample_weights)
    "mlt.cl": ["mlt", "mlt/pool", "mlt/resample"],
}
# Kernels in a program that no variant launches, but an assignment's checks do (by position), with
# the file that launches them: the grader's own tests (tests/test_assignments.py) run them.
GRADED = {"pt_inplace_regen.cl": {"pt_inplace_regen_regenerate": "toolkit/grading/checks/inplace_regen.py"}}
SCALARS = {np.int32: "int", np.uint32: "uint", np.float32: "float"}
RECORD_NAMES = {record.dtype: record.name for record in RECORDS}


def host_kind(value):
    """What the host passes: "pointer" (a buffer), a scalar's C type, or a record's C name."""
    if isinstance(value, cl.MemoryObjectHolder):
        return "pointer"
    if isinstance(value, np.void):
        return RECORD_NAMES.get(value.dtype, f"a record of no layout.py type {value.dtype}")
    return SCALARS.get(type(value), type(value).__name__)


def kernel_kind(type_name):
    """The same for a kernel parameter, from its type name (get_arg_info TYPE_NAME)."""
    return "pointer" if type_name.rstrip().endswith("*") else type_name.strip()


def kernel_parameters(tech):
    """{kernel name: [(parameter name, kind), ...]} of the technique's program, as compiled."""
    built = program.build(tech.queue, tech.source, tech.defines, directory=tech.sources, arg_info=True)
    return {k.function_name: [(k.get_arg_info(i, cl.kernel_arg_info.NAME),
                               kernel_kind(k.get_arg_info(i, cl.kernel_arg_info.TYPE_NAME)))
                              for i in range(k.num_args)]
            for k in built.all_kernels()}


def check_call(kernel, call, parameters):
    """`call`: (name or None when passed by position, kind) of each argument of one launch of
    `kernel`; `parameters`: the kernel's (name, kind) of each. No argument may be passed by position."""
    assert len(call) == len(parameters), f"{kernel}: {len(call)} arguments for {len(parameters)} parameters"
    kinds = [(i, host, device) for i, ((_, host), (_, device)) in enumerate(zip(call, parameters)) if host != device]
    assert not kinds, f"{kernel}: (argument, host kind, kernel kind) that differ: {kinds}"
    names = [(host, device) for (host, _), (device, _) in zip(call, parameters) if host is not None]
    wrong = [(host, device) for host, device in names if host != device]
    assert not wrong, f"{kernel}: (host name, kernel name) that differ: {wrong}"
    assert len(names) == len(parameters), f"{kernel}: some arguments passed by position"


def checked_render(monkeypatch, tech, parameters):
    """Render a small image with `tech` (SIMD counters on: every buffer a kernel writes is in use),
    each launch checked against `parameters` before it runs (a wrong argument may crash the
    render or make it run on and on); returns the names of the kernels launched."""
    launched = set()
    real = Kernels.launch

    def checked(self, kernel, n, /, *args, **named):
        kernel = self.kernel(kernel) if isinstance(kernel, str) else kernel
        call = [(None, host_kind(v)) for v in args] + [(name, host_kind(v)) for name, v in named.items()]
        check_call(kernel.function_name, call, parameters[kernel.function_name])
        launched.add(kernel.function_name)
        return real(self, kernel, n, *args, **named)

    with monkeypatch.context() as patch:
        patch.setattr(Kernels, "launch", checked)
        tech.render(8, 8, 2, seed=1)
    return launched


@pytest.mark.parametrize("source", sorted(PROGRAMS))
def test_every_kernel_is_launched_with_its_parameters_names_and_kinds(monkeypatch, queue, cornell_box, source):
    launched, parameters = set(), {}
    for variant in PROGRAMS[source]:
        cls, options = get_technique(variant)
        tech = cls(queue, DeviceScene(queue, cornell_box), **options)
        assert tech.source == source
        parameters = parameters or kernel_parameters(tech)
        launched |= checked_render(monkeypatch, tech, parameters)
    graded = GRADED.get(source, {})
    for kernel, checks in graded.items():
        assert f'"{kernel}"' in (ROOT / checks).read_text(), f"{checks} no longer launches {kernel}"
    assert launched | set(graded) == set(parameters), "kernels in the program that no variant launches, or the reverse"


def test_a_wrong_name_order_or_kind_is_seen(queue, cornell_box):
    """The comparison can fail: two arguments swapped, one of another kind, one by position."""
    tech = get_technique("pt_naive")[0](queue, DeviceScene(queue, cornell_box))
    parameters = kernel_parameters(tech)["pt_naive_render"]
    right = list(parameters)
    assert [name for name, _ in right][-3:] == ["pass_args", "radiance", "lane_counts"]
    assert right[-3][1] == "PtPass" and right[-1][1] == "pointer"
    check_call("pt_naive_render", right, parameters)
    for wrong in (right[:-2] + [right[-1], right[-2]], right[:-3] + [("pass_args", "int")] + right[-2:],
                  right[:-1] + [(None, "pointer")]):
        with pytest.raises(AssertionError):
            check_call("pt_naive_render", wrong, parameters)
    assert host_kind(np.uint32(1)) == "uint" and host_kind(tech.scene.camera(4, 4)) == "Camera"
