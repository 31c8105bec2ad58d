"""The index arithmetic host and kernels share (toolkit/core/bdpt_indices.py, sample_dims.py) is
written once in Python and generated into layout.h: the host's function and the kernel's helper
give the same numbers over ranges of inputs, and the generated C reads its inputs by name."""
import itertools

import numpy as np
import pyopencl as cl
import pytest

from toolkit.core import bdpt_indices as bi
from toolkit.core import sample_dims as sd
from toolkit.core.c_formula import Var, c_helper, where
from toolkit.core.layout import c_header
from toolkit.opencl import program

# (what, C expression of the inputs a, b, c (ints >= 0; b >= 1), the same on the host)
CASES = [
    ("connection_count", "connection_count(a, b)", lambda a, b, c: bi.connection_count(a, b)),
    ("connection_strategy s", "s", lambda a, b, c: bi.connection_strategy(a, b)[0]),
    ("connection_strategy t", "t", lambda a, b, c: bi.connection_strategy(a, b)[1]),
    ("strategy_count", "strategy_count(c)", lambda a, b, c: bi.strategy_count(c)),
    ("strategy_index", "strategy_index(a, b, c)", lambda a, b, c: bi.strategy_index(a, b, c)),
    ("naive_splat_record", "naive_splat_record(a, b)", lambda a, b, c: bi.naive_splat_record(a, b)),
    ("naive_sum_record", "naive_sum_record(a, b)", lambda a, b, c: bi.naive_sum_record(a, b)),
    ("naive_strategy_record", "naive_strategy_record(a, b, c, a + c, b)",
     lambda a, b, c: bi.naive_strategy_record(a, b, c, a + c, b)),
    ("naive_record_count", "naive_record_count(a, b, c)", lambda a, b, c: bi.naive_record_count(a, b, c)),
    ("bounce_dim", "(int)bounce_dim(a, (uint)c)", lambda a, b, c: sd.bounce_dim(a, c)),
    ("bdpt_scatter_dim", "(int)bdpt_scatter_dim(b, (c & 1) != 0, (uint)a % 4u)",
     lambda a, b, c: sd.bdpt_scatter_dim(b, c % 2 == 1, a % 4)),
    ("used_dims", "used_dims(b, c)", lambda a, b, c: sd.used_dims(b, c)),
]

KERNEL = """
__kernel void shared_indices(const int n, __global const int* in_a, __global const int* in_b,
                             __global const int* in_c, __global int* out) {
    int i = get_global_id(0);
    if (i >= n) return;
    int a = in_a[i], b = in_b[i], c = in_c[i], s, t;
    connection_strategy(a, b, &s, &t);
""" + "".join(f"    out[{k} * n + i] = {expr};\n" for k, (_, expr, _) in enumerate(CASES)) + "}\n"


def test_host_and_kernel_compute_the_same_indices(queue, tmp_path):
    (tmp_path / "shared_indices.cl").write_text('#include "common.h"\n' + KERNEL)
    built = program.build(queue, "shared_indices.cl", directory=tmp_path)
    a, b, c = (np.array(x, np.int32) for x in zip(*itertools.product(range(0, 40), range(1, 40), range(0, 12))))
    n = len(a)
    mf = cl.mem_flags
    buffers = [cl.Buffer(queue.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=x) for x in (a, b, c)]
    out = np.zeros((len(CASES), n), np.int32)
    out_buffer = cl.Buffer(queue.context, mf.WRITE_ONLY, out.nbytes)
    program.kernel(built, "shared_indices")(queue, (n,), None, np.int32(n), *buffers, out_buffer)
    cl.enqueue_copy(queue, out, out_buffer)
    host = [a.astype(np.int64), b.astype(np.int64), c.astype(np.int64)]
    wrong = [what for k, (what, _, function) in enumerate(CASES)
             if not np.array_equal(np.broadcast_to(function(*host), (n,)), out[k])]
    assert not wrong, wrong


def test_every_shared_helper_is_in_the_generated_header():
    header = c_header()
    for name in ["connection_count", "connection_strategy", "strategy_count", "strategy_index",
                 "naive_splat_record", "naive_sum_record", "naive_strategy_record", "naive_record_count",
                 "bounce_dim", "bdpt_scatter_dim"]:
        assert f" {name}(" in header, name
    assert "#define BDPT_DIM_EMIT_DIR 5" in header and "#define DIM_ROULETTE 6" in header


def test_a_formula_becomes_c_with_its_parameters_and_choices():
    def halve_or_zero(x, limit):
        """x / 2 up to limit."""
        return where(x <= limit, x // 2, 0)
    assert c_helper(halve_or_zero, [("x", "int"), ("limit", "int")]).endswith(
        "HELPER int halve_or_zero(int x, int limit) { return (int)((x <= limit) ? (x / 2) : 0); }")
    assert str(3 - Var("k") * 2) == "(3 - (k * 2))"
    assert int(halve_or_zero(7, 8)) == 3 and int(halve_or_zero(9, 8)) == 0


def test_mlt_counts_the_dimensions_the_bdpt_table_gives_each_vertex():
    # the last scattering of a sample with eye and light subpaths of 3 and 5 vertices is at light vertex 4
    last = sd.bdpt_scatter_dim(4, True, sd.BdptScatterDim.ROULETTE)
    assert int(sd.used_dims(3, 5)) == int(sd.bdpt_scatter_dim(5, False, 0)) == last + 1
