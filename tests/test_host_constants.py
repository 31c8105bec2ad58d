"""Issue 41 item 5: every constant that host and device share is set by the host, and the device
stops its build with #error when one is missing; the limits derive from one value
(toolkit/core/layout.py LONGEST_SUBPATH)."""
import inspect

import pytest

from toolkit.core.render_options import RenderOptions
from toolkit.core.layout import LONGEST_SUBPATH
from toolkit.core.sample_dims import used_dims
from toolkit.core.validate import LIMITS
from toolkit.opencl import program
from toolkit.techniques.bdpt_evaluator import BdptPoolTechnique
from toolkit.techniques.mlt import Mlt


@pytest.mark.parametrize("header, define", [("vertex_memory.h", "MAX_VERTICES"),
                                            ("mlt_proposals.h", "MLT_MAX_DIMS")])
def test_a_constant_the_host_did_not_set_stops_the_build(queue, tmp_path, header, define):
    """No default on the device: a program built without the host's value fails, naming it."""
    (tmp_path / "uses_it.cl").write_text(f'#include "{header}"\n__kernel void k(__global int* out) {{ out[0] = 0; }}\n')
    with pytest.raises(program.KernelBuildError, match=define):
        program.build(queue, "uses_it.cl", {"LOCAL_SIZE": program.LOCAL_SIZE},
                      directory=program.default_sources(tmp_path))


def test_a_vertex_count_past_the_longest_subpath_stops_the_build(queue):
    with pytest.raises(program.KernelBuildError, match="LONGEST_SUBPATH"):
        program.build(queue, "index_test.cl", {"MAX_VERTICES": LONGEST_SUBPATH + 1})


def test_the_limits_derive_from_the_longest_subpath():
    assert LIMITS["integrator.max_depth"][1] == LONGEST_SUBPATH - 1      # max_depth edges: one vertex more
    assert LIMITS["mlt.max_dims"][1] == used_dims(LONGEST_SUBPATH, LONGEST_SUBPATH)
    assert BdptPoolTechnique.max_vertices == LONGEST_SUBPATH
    assert inspect.signature(Mlt).parameters["max_dims"].default == used_dims(16, 16) == 128


def test_render_uses_the_programs_work_group_size():
    assert RenderOptions().local_size == program.LOCAL_SIZE
