"""toolkit/opencl/program.py: build errors that point into our files, memoised builds, scene-specialised
builds (absent materials are not compiled), and the fixed local size with a padded global size.

Test kernels are written to tmp_path and built with `program.build(..., directory=tmp_path)`;
their quoted includes are looked up there first, then in cl/.
"""
import os
import time

import numpy as np
import pyopencl as cl
import pytest

from toolkit.opencl import program
from toolkit.opencl.device import candidates
from toolkit.opencl.program import KernelBuildError


def write(folder, name, text):
    (folder / name).write_text(text)
    return name


def nonce():
    """A define value no earlier build used: makes a build that cannot be memoised yet."""
    return f"{os.getpid()}{time.time_ns()}"


# -- (a) build errors name our files and lines ------------------------------------------------

BROKEN_H = """/* a header with a mistake on line 3 */
inline int fine(int x) { return x + 1; }
inline int broken(int x) { return x + undefined_in_header; }
"""

BROKEN_CL = """/* includes the broken header */
#include "broken.h"
__kernel void use_broken(__global int* out) {
    out[0] = broken(1);
}
"""


IMPLEMENTATIONS = [c for c in candidates() if c.usable]


def queue_of(implementation):
    from toolkit.opencl.device import queue_for_device
    return queue_for_device(implementation.device)


@pytest.mark.parametrize("implementation", IMPLEMENTATIONS, ids=lambda c: c.implementation)
def test_error_in_included_header_names_its_file_and_line(implementation, tmp_path):
    """On every implementation: compilers write the location in different places (PoCL after
    "error:", Intel before it, and Intel's log only reaches us through pyopencl's error text)."""
    write(tmp_path, "broken.h", BROKEN_H)
    write(tmp_path, "broken.cl", BROKEN_CL)
    with pytest.raises(KernelBuildError) as info:
        program.build(queue_of(implementation), "broken.cl", {}, directory=tmp_path)
    message = str(info.value)
    assert "OpenCL build of broken.cl failed" in message
    assert "broken.h:3" in message, message
    assert "undefined_in_header" in message
    # The summary lists the lines that point into our sources before the full log.
    summary = message.split("Full compiler log:")[0]
    assert "Errors in our sources:" in summary and "broken.h:3" in summary, message


def test_error_after_an_include_names_the_right_line(queue, tmp_path):
    write(tmp_path, "fine.h", "/* line 1 */\ninline int fine(int x) { return x + 1; }\n")
    write(tmp_path, "broken_main.cl", """/* line 1 */
#include "fine.h"
#include "common.h"
__kernel void k(__global int* out) {
    out[0] = fine(1) + undefined_in_kernel;
}
""")
    with pytest.raises(KernelBuildError) as info:
        program.build(queue, "broken_main.cl", {}, directory=tmp_path)
    message = str(info.value)
    assert "broken_main.cl:5" in message, message
    assert "fine.h" not in message.split("Full compiler log:")[0]


def test_missing_source_is_a_build_error(queue, tmp_path):
    write(tmp_path, "includes_missing.cl", '#include "no_such_header.h"\n__kernel void k() {}\n')
    with pytest.raises(KernelBuildError, match="no_such_header.h"):
        program.build(queue, "includes_missing.cl", {}, directory=tmp_path)
    with pytest.raises(KernelBuildError, match="not found"):
        program.build(queue, "no_such_kernel.cl", {}, directory=tmp_path)


def test_expand_includes_inlines_each_header_once_with_line_markers():
    source = program.expand_includes("materials.h")
    assert source.count('#line 1 "common.h"') == 1
    assert source.count('#line 1 "materials.h"') == 1
    assert '#include "' not in source
    # After an include the including file resumes on its own next line.
    lines = (program.cl_dir() / "materials.h").read_text().splitlines()
    include_line = next(i for i, t in enumerate(lines, 1) if '#include "common.h"' in t)
    assert f'#line {include_line + 1} "materials.h"' in source


def test_the_toolkits_own_sources_are_put_together_again_only_when_a_file_changes(monkeypatch, tmp_path):
    """expand_includes keeps the text of the toolkit's own programs (a render builds several, and each
    took milliseconds to put together again), and reads them again once one of their files changes."""
    import shutil
    cl = tmp_path / "cl"
    shutil.copytree(program.cl_dir(), cl)
    monkeypatch.setattr(program, "cl_dir", lambda: cl)
    first = program.expand_includes("materials.h")
    assert program.expand_includes("materials.h") is first          # kept: the same text, not read again
    assert "twice_the_pi" not in first
    common = cl / "common.h"                                         # included by materials.h
    common.write_text(common.read_text() + "#define twice_the_pi 6.28f\n")
    again = program.expand_includes("materials.h")
    assert again is not first and "#define twice_the_pi 6.28f" in again
    # A folder of the caller's is read every time: a file there may replace the toolkit's.
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "common.h").write_text("#define MINE 1\n")
    assert "#define MINE 1" in program.expand_includes("materials.h", folder)
    (folder / "common.h").write_text("#define MINE 2\n")
    assert "#define MINE 2" in program.expand_includes("materials.h", folder)


def test_define_options_drop_false_and_none_and_mark_floats():
    options = program.define_options({"B": True, "A": False, "C": None, "D": 3, "E": 0.5})
    assert options == ["-DB=1", "-DD=3", "-DE=0.5f"]


# -- (b) memoisation --------------------------------------------------------------------------

TINY = """__kernel void tiny(__global int* out) {
    out[get_global_id(0)] = TINY_VALUE;
}
"""


def test_builds_are_memoised(queue, tmp_path):
    write(tmp_path, "tiny.cl", TINY)
    defines = {"TINY_VALUE": 7, "NONCE": nonce()}
    log = queue.builds.log
    first = program.build(queue, "tiny.cl", defines, directory=tmp_path)
    assert log[-1][0] == "tiny.cl" and log[-1][2] is False
    second = program.build(queue, "tiny.cl", dict(defines), directory=tmp_path)
    assert second is first
    assert log[-1] == ("tiny.cl", 0.0, True)
    other = program.build(queue, "tiny.cl", dict(defines, TINY_VALUE=8), directory=tmp_path)
    assert other is not first
    assert log[-1][2] is False
    # The defines really reach the compiler.
    out = cl.Buffer(queue.context, cl.mem_flags.WRITE_ONLY, 4)
    values = []
    for built in (first, other):
        program.kernel(built, "tiny")(queue, (1,), None, out)
        value = np.zeros(1, np.int32)
        cl.enqueue_copy(queue, value, out)
        values.append(int(value[0]))
    assert values == [7, 8]
    assert program.kernel(first, "tiny") is program.kernel(first, "tiny")


def test_each_context_has_builds_of_its_own(queue, tmp_path):
    """What is built is kept by the context's Builds, which its queues carry (builds.py), not by
    a module: the profiling queue of a context shares it, a new context starts with nothing."""
    from toolkit.opencl.builds import Builds, Queue
    from toolkit.opencl.kernel_times import profiling_queue
    write(tmp_path, "tiny.cl", TINY)
    defines = {"TINY_VALUE": 3, "NONCE": nonce()}
    first = program.build(queue, "tiny.cl", defines, directory=tmp_path)
    timed = profiling_queue(queue)
    assert timed is not queue and timed.builds is queue.builds and profiling_queue(queue) is timed
    assert program.build(timed, "tiny.cl", defines, directory=tmp_path) is first
    fresh = Queue(cl.Context([queue.device]), Builds(queue.builds.lanes))
    again = program.build(fresh, "tiny.cl", defines, directory=tmp_path)
    assert again is not first and fresh.builds.log == [("tiny.cl", fresh.builds.log[0][1], False)]
    assert fresh.builds.programs and not set(fresh.builds.programs.values()) & set(queue.builds.programs.values())


def test_changed_source_is_rebuilt(queue, tmp_path):
    write(tmp_path, "tiny.cl", TINY)
    defines = {"TINY_VALUE": 1, "NONCE": nonce()}
    first = program.build(queue, "tiny.cl", defines, directory=tmp_path)
    write(tmp_path, "tiny.cl", TINY + "/* edited */\n")
    assert program.build(queue, "tiny.cl", defines, directory=tmp_path) is not first


# -- (c) scene-specialised builds -------------------------------------------------------------

def test_cornell_box_compiles_in_only_diffuse(cornell_box):
    f = cornell_box.features()
    assert f["HAS_DIFFUSE"] is True
    for absent in ("HAS_DIELECTRIC", "HAS_MIRROR", "HAS_GLOSSY", "HAS_SPECULAR"):
        assert f[absent] is False, absent
    options = program.define_options(f)
    assert "-DHAS_DIFFUSE=1" in options
    assert not any(o.startswith(("-DHAS_DIELECTRIC", "-DHAS_MIRROR", "-DHAS_GLOSSY")) for o in options)


def test_cornell_spheres_compiles_in_mirror_and_dielectric(cornell_spheres):
    f = cornell_spheres.features()
    assert f["HAS_MIRROR"] and f["HAS_DIELECTRIC"] and f["HAS_DIFFUSE"] and f["HAS_SPECULAR"]
    assert not f["HAS_GLOSSY"]


USES_FRESNEL = """#include "materials.h"
__kernel void uses_fresnel(__global float* out) {
    float cos_t;
    out[0] = fresnel_dielectric(0.5f, 1.5f, &cos_t);
}
"""

USES_GGX = """#include "materials.h"
__kernel void uses_ggx(__global float* out) {
    out[0] = ggx_d((float3)(0.0f, 0.0f, 1.0f), 0.3f);
}
"""


@pytest.mark.parametrize("source,symbol,feature", [
    (USES_FRESNEL, "fresnel_dielectric", "HAS_DIELECTRIC"),
    (USES_GGX, "ggx_d", "HAS_GLOSSY"),
])
def test_absent_materials_are_compiled_out(queue, tmp_path, cornell_box, source, symbol, feature):
    """Code that only an absent material uses is not in the program: calling it fails to build."""
    name = write(tmp_path, f"uses_{symbol}.cl", source)
    defines = cornell_box.features()
    with pytest.raises(KernelBuildError) as info:
        program.build(queue, name, defines, directory=tmp_path)
    assert symbol in str(info.value)
    assert f"{name}:" in str(info.value)
    program.build(queue, name, dict(defines, **{feature: True}), directory=tmp_path)


IS_SPECULAR = """#include "materials.h"
__kernel void specular_types(__global int* out) {
    out[0] = is_specular(MAT_DIFFUSE);
    out[1] = is_specular(MAT_MIRROR);
    out[2] = is_specular(MAT_DIELECTRIC);
}
"""


def test_specular_branches_follow_the_scene(queue, tmp_path, cornell_box, cornell_spheres):
    """is_specular() only knows the materials the scene has: with the box's defines the mirror
    and glass branches are gone; with the spheres' they are there."""
    name = write(tmp_path, "specular_types.cl", IS_SPECULAR)
    out = cl.Buffer(queue.context, cl.mem_flags.WRITE_ONLY, 12)
    results = {}
    for scene in (cornell_box, cornell_spheres):
        built = program.build(queue, name, scene.features(), directory=tmp_path)
        program.kernel(built, "specular_types")(queue, (1,), None, out)
        values = np.zeros(3, np.int32)
        cl.enqueue_copy(queue, values, out)
        results[scene.name] = values.tolist()
    assert results == {"cornell_box": [0, 0, 0], "cornell_spheres": [0, 1, 1]}


def test_each_scene_gets_its_own_pt_naive_build(queue, cornell_box, cornell_spheres):
    box = program.build(queue, "pt_naive.cl", cornell_box.features())
    spheres = program.build(queue, "pt_naive.cl", cornell_spheres.features())
    assert box is not spheres
    assert program.kernel(box, "pt_naive_render") is not None


# -- (d) fixed local size, padded global size -------------------------------------------------

FILL = """__kernel void fill(const int n, __global int* out, __global int* sizes) {
    int gid = get_global_id(0);
    if (gid == 0) {
        sizes[0] = (int)get_global_size(0);
        sizes[1] = (int)get_local_size(0);
    }
    if (gid >= n) return;
    out[gid] = gid + 1;
}
"""


def test_padded_rounds_up_to_a_multiple_of_the_local_size():
    L = program.LOCAL_SIZE
    assert L == 64
    assert [program.padded(n) for n in (0, 1, L - 1, L, L + 1, 10 * L, 10 * L + 3)] == \
        [L, L, L, L, 2 * L, 10 * L, 11 * L]
    assert program.padded(33, 32) == 64
    assert all(program.padded(n) % L == 0 and program.padded(n) >= n for n in range(1, 1000, 7))


@pytest.mark.parametrize("n", [1, 64, 65, 1000])
def test_launch_uses_fixed_local_size_and_padded_global_size(queue, tmp_path, n):
    name = write(tmp_path, "fill.cl", FILL)
    built = program.build(queue, name, {}, directory=tmp_path)
    out = cl.Buffer(queue.context, cl.mem_flags.READ_WRITE, 4 * (n + 1))
    cl.enqueue_fill_buffer(queue, out, np.int32(-1), 0, 4 * (n + 1))
    sizes = cl.Buffer(queue.context, cl.mem_flags.WRITE_ONLY, 8)
    program.launch(queue, program.kernel(built, "fill"), n, np.int32(n), out, sizes)
    values = np.zeros(n + 1, np.int32)
    got = np.zeros(2, np.int32)
    cl.enqueue_copy(queue, values, out)
    cl.enqueue_copy(queue, got, sizes)
    assert got.tolist() == [program.padded(n), program.LOCAL_SIZE]
    np.testing.assert_array_equal(values[:n], np.arange(1, n + 1))
    assert values[n] == -1   # the padding work-items wrote nothing


WARNING_CL = "__kernel void k(__global int* out) { int truncated = 1.5f; out[0] = truncated; }\n"


@pytest.mark.parametrize("implementation", IMPLEMENTATIONS, ids=lambda c: c.implementation)
def test_compiler_warnings_are_shown_and_fail_the_suite(implementation, tmp_path, monkeypatch):
    """On every implementation: a warning is shown once as a KernelBuildWarning that names our
    file and line (not pyopencl's CompilerWarning for any non-empty log, which Intel's progress
    remarks would trigger on every build), and with -Werror (the suite's setting) it fails."""
    import warnings
    # A source never built before: a cached binary comes without its build log (and warnings).
    write(tmp_path, "warns.cl", WARNING_CL + f"/* {tmp_path} {time.time()} */\n")
    queue = queue_of(implementation)
    monkeypatch.delenv("TOOLKIT_WERROR")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        program.build(queue, "warns.cl", {}, directory=tmp_path)
    assert [w.category for w in caught] == [program.KernelBuildWarning], [str(w.message) for w in caught]
    assert "warns.cl:1:" in str(caught[0].message)
    monkeypatch.setenv("TOOLKIT_WERROR", "1")
    with pytest.raises(KernelBuildError, match="warns.cl:1:"):
        program.build(queue, "warns.cl", {}, directory=tmp_path)


def test_a_compilers_notice_about_itself_is_no_warning():
    """NVIDIA's OpenCL compiler (driver 580) writes this for every kernel it builds; a real
    warning beside it still counts."""
    from toolkit.opencl.program import warning_lines
    log = ("(): Warning: Function pt_naive_render is a kernel, so overriding noinline attribute. "
           "The function may be inlined when called.\n"
           "<source>:12:5: warning: unused variable 'x'\n")
    assert warning_lines(log) == ["<source>:12:5: warning: unused variable 'x'"]


ARGS_CL = """typedef struct { int a; int b; } Pair;
__kernel void args(const int n, const Pair pair, __global int* out) {
    if (get_global_id(0) == 0) { out[0] = n; out[1] = pair.a; out[2] = pair.b; }
}
"""


def test_launch_sets_what_changed_and_sees_a_record_changed_in_place(queue, tmp_path):
    """launch skips an argument given as the very object of the last launch (a buffer, a number)
    but a record (np.void) may change in place: it is compared by its bytes every time."""
    built = program.build(queue, write(tmp_path, "args.cl", ARGS_CL), {}, directory=tmp_path)
    kernel = program.kernel(built, "args")
    pair = np.zeros(1, np.dtype([("a", np.int32), ("b", np.int32)]))[0]
    outs = [cl.Buffer(queue.context, cl.mem_flags.READ_WRITE, 12) for _ in range(2)]

    def run(n, out):
        program.launch(queue, kernel, 1, n, pair, out)
        got = np.zeros(3, np.int32)
        cl.enqueue_copy(queue, got, out)
        return got.tolist()
    three = np.int32(3)
    pair["a"], pair["b"] = 1, 2
    assert run(three, outs[0]) == [3, 1, 2]
    pair["a"] = 7                                   # the same record object, changed in place
    assert run(three, outs[0]) == [3, 7, 2]
    assert run(np.int32(4), outs[0]) == [4, 7, 2]   # an equal or new number, another object
    assert run(three, outs[1]) == [3, 7, 2]         # another buffer
    assert run(three, outs[0]) == [3, 7, 2] and run(np.int32(3), outs[1]) == [3, 7, 2]


def test_a_frozen_record_is_known_by_its_object_and_cannot_change_in_place(queue, tmp_path, monkeypatch):
    """A read-only record (record.frozen, what Record.record and the camera give) is set once: the
    same object given again is not compared by its bytes; a new frozen record with other values is set."""
    from toolkit.core.record import frozen
    built = program.build(queue, write(tmp_path, "args.cl", ARGS_CL), {}, directory=tmp_path)
    kernel = program.kernel(built, "args")
    pair_type = np.dtype([("a", np.int32), ("b", np.int32)])

    def made(a, b):
        records = np.zeros(1, pair_type)
        records[0]["a"], records[0]["b"] = a, b
        return frozen(records)
    out = cl.Buffer(queue.context, cl.mem_flags.READ_WRITE, 12)
    looked_at = []
    real = program._fingerprint
    monkeypatch.setattr(program, "_fingerprint", lambda value: looked_at.append(value) or real(value))

    def run(n, pair):
        program.launch(queue, kernel, 1, n, pair, out)
        got = np.zeros(3, np.int32)
        cl.enqueue_copy(queue, got, out)
        return got.tolist()
    three, pair = np.int32(3), made(1, 2)
    with pytest.raises(ValueError):
        pair["a"] = 7                                # read-only
    assert run(three, pair) == [3, 1, 2] and len(looked_at) == 3     # the first launch sets all three
    assert run(three, pair) == [3, 1, 2] and len(looked_at) == 3     # the same objects: nothing looked at
    assert run(three, made(5, 6)) == [3, 5, 6] and len(looked_at) == 4


def test_a_kernel_copy_per_turn_of_swapping_buffers_sets_no_argument_again(queue, tmp_path, monkeypatch):
    """program.kernel(..., copy=k) is one kernel object per copy, each retrieved once; launch keeps
    each one's arguments, so buffers that take turns (pt_compact_regen's streams) are set once per copy."""
    built = program.build(queue, write(tmp_path, "args.cl", ARGS_CL), {}, directory=tmp_path)
    copies = [program.kernel(built, "args", copy=k) for k in (0, 1)]
    assert copies[0] is not copies[1]
    assert copies == [program.kernel(built, "args", copy=k) for k in (0, 1)] and copies[0] is program.kernel(built, "args")
    set_args = []
    real = program._set_arg
    monkeypatch.setattr(program, "_set_arg", lambda kernel, i, value: set_args.append(i) or real(kernel, i, value))
    outs = [cl.Buffer(queue.context, cl.mem_flags.READ_WRITE, 12) for _ in range(2)]
    n, pair = np.int32(3), np.zeros(1, np.dtype([("a", np.int32), ("b", np.int32)]))[0]
    for step in range(2):
        program.launch(queue, copies[step], 1, n, pair, outs[step])
    assert set_args.count(2) == 2                       # each copy's first launch set its buffer
    set_args.clear()
    for step in range(2, 6):
        program.launch(queue, copies[step % 2], 1, n, pair, outs[step % 2])
    assert set_args == []                               # then each turn finds its arguments set
    got = np.zeros(3, np.int32)
    cl.enqueue_copy(queue, got, outs[1])
    assert got.tolist() == [3, 0, 0]
