"""cl/inline_builtins.h: the built-ins written out for PoCL give OpenCL's own results, for every
argument type it overloads (a student's file may use any of them). One kernel evaluates each on
random inputs, built twice: with BUILTINS_ARE_CALLS (ours) and without (the compiler's)."""
import numpy as np
import pyopencl as cl
import pytest

from toolkit.opencl import program

# One output float per line; each expression reads the inputs a, b (float4) and s (float).
EXPRESSIONS = [
    "sqrt(s)", "rsqrt(s)", "fabs(a.x)", "fmin(a.x, b.x)", "fmax(a.x, b.x)", "copysign(a.x, b.x)",
    "(float)isfinite(a.x / b.y)",
    "dot(a.x, b.x)", "dot(a.xy, b.xy)", "dot(a.xyz, b.xyz)", "dot(a, b)",
    "length(a.x)", "length(a.xy)", "length(a.xyz)", "length(a)",
    "normalize(a.xy).y", "normalize(a.xyz).z", "normalize(a).w",
    "cross(a.xyz, b.xyz).x", "cross(a.xyz, b.xyz).y", "cross(a, b).z", "cross(a, b).w",
    "fmin(a.xy, b.xy).y", "fmin(a.xyz, b.xyz).z", "fmin(a, b).w", "fmin(a.xyz, s).y", "fmin(a, s).w",
    "fmax(a.xy, b.xy).y", "fmax(a.xyz, b.xyz).z", "fmax(a, b).w", "fmax(a.xy, s).x", "fmax(a, s).w",
    "fabs(a.xy).y", "fabs(a.xyz).z", "fabs(a).w", "sqrt(fabs(a)).w", "sqrt(fabs(a.xyz)).y",
]

KERNEL = """#include "common.h"
__kernel void builtins(__global const float4* as, __global const float4* bs, __global float* out) {
    int i = get_global_id(0);
    float4 a = as[i], b = bs[i];
    float s = fabs(a.w) + 1e-3f;
    __global float* o = out + i * %d;
%s
}
"""


def test_written_out_builtins_match_the_compilers_own(queue, tmp_path):
    if not program.builtins_are_calls(queue.device):
        pytest.skip("the default device inlines its own built-ins: inline_builtins.h is not used there")
    lines = "\n".join(f"    o[{k}] = {e};" for k, e in enumerate(EXPRESSIONS))
    (tmp_path / "builtins.cl").write_text(KERNEL % (len(EXPRESSIONS), lines))
    rng = np.random.default_rng(7)
    n = 4096
    a = rng.normal(0, 10, (n, 4)).astype(np.float32)
    b = rng.normal(0, 10, (n, 4)).astype(np.float32)
    a[:16] = 0.0                                       # zero vectors: normalize returns them unchanged
    b[16:32, 1] = 0.0                                  # a.x / 0: isfinite sees infinities
    outputs = []
    for ours in (True, False):
        built = program.build(queue, "builtins.cl", {"BUILTINS_ARE_CALLS": ours}, directory=tmp_path)
        mf = cl.mem_flags
        bufs = [cl.Buffer(queue.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=x) for x in (a, b)]
        out = np.empty((n, len(EXPRESSIONS)), np.float32)
        out_buf = cl.Buffer(queue.context, mf.WRITE_ONLY, out.nbytes)
        program.kernel(built, "builtins")(queue, (n,), None, *bufs, out_buf)
        cl.enqueue_copy(queue, out, out_buf)
        outputs.append(out)
    ours, theirs = outputs
    eps = np.finfo(np.float32).eps
    terms = np.abs(a) @ np.ones(4) * np.abs(b).max(axis=1)   # bounds the sum of |a_i b_i| of any dot or cross here
    for k, e in enumerate(EXPRESSIONS):
        if e.startswith(("dot", "cross")):
            # a sum of products: its rounding error is relative to the terms, not to a result that
            # may cancel to near zero; 4 ulps of the terms allow another order or a fused multiply-add
            tol = 4 * eps * terms
        elif e.startswith(("sqrt", "rsqrt", "length", "normalize")):
            tol = 4 * eps * np.abs(theirs[:, k])   # OpenCL allows these a few ulps (rsqrt 2, normalize 3)
        else:
            tol = 0.0                              # fabs, fmin, fmax, copysign, isfinite: exact
        bad = ~(np.abs(ours[:, k] - theirs[:, k]) <= tol)
        assert not bad.any(), f"{e}: {int(bad.sum())} differ, first {ours[bad, k][:3]} against {theirs[bad, k][:3]}"
