"""`gpucheck --offline`: the kernels built for GPUs without one (toolkit/verify/offline_build.py).

The builds need clang with libclc (Debian: clang-16 and libclc-16, which .ci/run installs) and
are skipped, saying so, without them; ptxas is used where found, else the PTX is checked. The
suite builds a representative subset (one scene, with the most materials; every technique and
the one variant with code of its own; the counters on: a superset of the code); the command
builds them all (every scene and variant, counters on and off: about 80 s on 2 cores).
"""
import functools
import json
import re

import pyopencl as cl
import pytest

from toolkit.cli import main
from toolkit.core.validate import InputError
from toolkit.opencl import program
from toolkit.opencl.device_film import has_fp64
from toolkit.techniques import TECHNIQUES
from toolkit.verify import gpu_programs, offline_build, offline_report
from toolkit.verify.gpu_compiler_reports import amdgcn_kernels, ptxas_kernels
from toolkit.verify.gpu_occupancy import warps_per_sm
from toolkit.verify.gpu_programs import HostBuild, host_builds, stand_in_device

# pt_compact_regen/multipass: the only technique left that builds compact.cl (pyopencl-free scans)
SUBSET = dict(scenes=["cornell_spheres"], counters=(True,),
              techniques=[*TECHNIQUES, "bdpt_parallel_connect/direct_scatter", "pt_compact_regen/multipass"])


def toolchain_or_skip():
    try:
        return offline_build.find_toolchain()
    except InputError as error:
        pytest.skip(f"no offline GPU build here: {error}")


# --- what is built: the host's own inputs, as on a GPU -------------------------------------------

def test_the_host_code_gives_every_program_with_a_gpus_defines():
    """Every technique and variant on every bundled scene, recorded from the host's constructors
    on a stand-in GPU: each technique's program is there, with the defines a GPU gets (no PoCL
    built-ins as calls, 4-wide BVH nodes, chain-minor MLT records), and pyopencl is left as it was."""
    saved = program.build, cl.Buffer, cl.Kernel
    for vendor in gpu_programs.GPU_MODELS:
        builds = host_builds(vendor)
        names = {build.name for build in builds}
        shared = {"compact.cl", "film_reduce.cl", "record_film.cl", "simd_counters.cl"}
        # the path tracers' device film: on a GPU with float64 (the MI210 model), not without (the H200 model)
        shared |= {"film_accumulate.cl"} if has_fp64(stand_in_device(vendor)) else set()
        assert {cls.source for cls in TECHNIQUES.values()} | shared == names
        for build in builds:
            assert not any(o.startswith(("-DBUILTINS_ARE_CALLS", "-DMLT_CHAIN_MAJOR")) for o in build.options), build.options
            if "-DBVH_WIDE=1" in build.options:
                assert "-DNODE_WIDTH=4" in build.options, build.options
            assert build.local_size == program.LOCAL_SIZE and build.uses
        # counters on and off, and the dielectric's code for cornell_spheres only
        naive = [build for build in builds if build.name == "pt_naive.cl"]
        assert {"-DCOUNT_SIMD=1" in b.options for b in naive} == {True, False}
        assert {"-DHAS_DIELECTRIC=1" in b.options for b in naive} == {True, False}
        assert any(use.startswith("cornell_spheres ") for b in naive if "-DHAS_DIELECTRIC=1" in b.options
                   for use in b.uses)
    assert (program.build, cl.Buffer, cl.Kernel) == saved


# --- what the compilers say, read ----------------------------------------------------------------

PTXAS_LOG = """ptxas info    : 0 bytes gmem
ptxas info    : Function properties for helper
    32 bytes stack frame, 8 bytes spill stores, 8 bytes spill loads
ptxas info    : Compiling entry function 'trace' for 'sm_90'
ptxas info    : Function properties for trace
    648 bytes stack frame, 4 bytes spill stores, 12 bytes spill loads
ptxas info    : Used 118 registers, used 1 barriers, 648 bytes cumulative stack size, 6660 bytes smem, 400 bytes cmem[0]
ptxas info    : Compiling entry function 'count' for 'sm_90'
ptxas info    : Function properties for count
    0 bytes stack frame, 0 bytes spill stores, 0 bytes spill loads
ptxas info    : Used 10 registers, used 0 barriers
"""


def test_ptxas_figures_per_kernel():
    assert ptxas_kernels(PTXAS_LOG) == {
        "trace": {"registers": 118, "stack_bytes": 648, "spill_bytes": 4, "spill_load_bytes": 12, "shared_bytes": 6660},
        "count": {"registers": 10, "stack_bytes": 0, "spill_bytes": 0, "spill_load_bytes": 0, "shared_bytes": 0}}


AMDGCN = """\t.size\ttrace, .Lfunc_end0-trace
; Kernel info:
; NumVgprs: 157
; Occupancy: 3
\t.size\tcount, .Lfunc_end1-count
; Occupancy: 8
\t.amdgpu_metadata
---
amdhsa.kernels:
  - .agpr_count:     0
    .args:
      - .offset:         0
        .size:           8
    .group_segment_fixed_size: 6672
    .name:           trace
    .private_segment_fixed_size: 540
    .sgpr_count:     102
    .sgpr_spill_count: 24
    .vgpr_count:     157
    .vgpr_spill_count: 2
  - .agpr_count:     0
    .name:           count
    .sgpr_count:     11
    .vgpr_count:     6
amdhsa.target:   amdgcn-amd-amdhsa--gfx90a
"""


def test_amdgcn_figures_per_kernel():
    assert amdgcn_kernels(AMDGCN) == {
        "trace": {"vgprs": 157, "sgprs": 102, "agprs": 0, "vgpr_spills": 2, "sgpr_spills": 24, "scratch_bytes": 540,
                  "lds_bytes": 6672, "waves_per_simd": 3},
        "count": {"vgprs": 6, "sgprs": 11, "agprs": 0, "vgpr_spills": 0, "sgpr_spills": 0, "scratch_bytes": 0,
                  "lds_bytes": 0, "waves_per_simd": 8}}


@pytest.mark.parametrize("registers, shared, warps, limit", [
    (118, 0, 16, "registers"),        # 3,840 registers a warp: 4 per sub-partition, 16 per SM
    (128, 0, 16, "registers"),
    (72, 0, 28, "registers"),         # 2,304 a warp: 7 per sub-partition = 28, 14 work-groups of 2
    (32, 0, 64, "warps"),             # at the SM's maximum: nothing the kernel asks for limits it
    (0, 0, 64, "warps"),
    (10, 100_000, 4, "shared memory"),  # 101,120 bytes a work-group with the driver's 1 KB: 2 fit in 228 KB
])
def test_warps_per_sm_on_sm90(registers, shared, warps, limit):
    occupancy = warps_per_sm(registers, shared, local_size=64)
    assert (occupancy.warps, occupancy.limited_by) == (warps, limit)


def test_work_groups_of_32_are_limited_by_their_count():
    assert warps_per_sm(10, 0, local_size=32).limited_by == "work-groups"   # 32 groups of one warp: half the SM
    with pytest.raises(ValueError, match="255"):
        warps_per_sm(256)


# --- the builds ----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def subset_report():
    return offline_build.run(**SUBSET, tools=toolchain_or_skip())


def declared_kernels(name):
    source = program.expand_includes(name)
    return set(re.findall(r"\b__kernel\b[^;{]*?\bvoid\s+(\w+)\s*\(", source))


def test_every_kernel_builds_for_both_gpus(subset_report):
    """Each kernel of each technique's program and of the shared ones, on nvptx64 (sm_90) and
    amdgcn (gfx90a), built; where ptxas ran, its figures are there (the path tracer's BVH stack
    is a private array: a stack frame in local memory)."""
    report = subset_report
    assert report["passed"], offline_report.format_report(report)
    for target in offline_build.TARGETS:
        built = {row["kernel"] for row in report["kernels"] if row["target"] == target.key and row["ok"]}
        for name in {cls.source for cls in TECHNIQUES.values()} | {"compact.cl", "film_reduce.cl", "record_film.cl",
                                                                   "simd_counters.cl"}:
            assert declared_kernels(name) <= built, (target.key, name, declared_kernels(name) - built)
    naive = {row["target"]: row for row in report["kernels"] if row["kernel"] == "pt_naive_render"}
    assert naive["amdgcn"]["vgprs"] > 0 and naive["amdgcn"]["waves_per_simd"] in range(1, 9)
    if report["ptxas"]:
        assert naive["nvptx64"]["registers"] > 0 and naive["nvptx64"]["stack_bytes"] > 0
        assert 0 < naive["nvptx64"]["warps_per_sm"] <= 64
    else:
        assert naive["nvptx64"]["assembled"] is False


def test_without_ptxas_the_ptx_is_still_made_for_sm90(tmp_path):
    tools = toolchain_or_skip()
    tools.ptxas = None
    builds = host_builds("nvidia", ["cornell_box"], ["pt_compact_regen/multipass"], (True,))
    compact = next(build for build in builds if build.name == "compact.cl")
    rows = offline_build.compile_program(compact, offline_build.TARGETS[0], tools, tmp_path)
    assert {row["kernel"] for row in rows} == declared_kernels("compact.cl")
    assert all(row["ok"] and row["assembled"] is False and row["registers"] is None for row in rows)


def test_a_kernel_that_does_not_build_names_its_file_and_line(monkeypatch, capsys):
    """On both targets: the kernel, its program, the renders that build it and clang's error at
    its file and line (the #line markers of program.expand_includes); exit code 1."""
    toolchain_or_skip()
    broken = HostBuild("broken.cl", '#line 1 "broken.h"\n__kernel void broken_kernel(__global int* out)\n'
                                    "{\n    out[0] = undeclared;\n}\n", ["-DLOCAL_SIZE=64"], 64, ["a test's scene"])
    monkeypatch.setattr(offline_build, "host_builds", lambda vendor, *selection: [broken])
    assert main(["gpucheck", "--offline"]) == 1
    printed = capsys.readouterr().out
    for target in ("nvptx64", "amdgcn"):
        assert f"FAILED `broken_kernel` for {target} (cl/broken.cl, used by a test's scene)" in printed
    assert printed.count("broken.h:3:14: error: use of undeclared identifier 'undeclared'") == 2
    assert "0 of 1 kernel builds succeeded" in printed and "2 kernel builds failed" in printed


# --- the command ---------------------------------------------------------------------------------

def test_command_prints_the_table_and_writes_the_json(tmp_path, monkeypatch, capsys):
    toolchain_or_skip()
    monkeypatch.setattr(offline_build, "run", functools.partial(
        offline_build.run, scenes=["cornell_box"], techniques=["pt_naive"], counters=(True,)))
    out = tmp_path / "offline.json"
    assert main(["gpucheck", "--offline", "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "| `pt_naive_render` | 1 | all |" in printed and "Every kernel built for every target." in printed
    report = json.loads(out.read_text())
    assert report["command"] == f"python -m toolkit gpucheck --offline --json {out}"
    rows = {(row["target"], row["kernel"]): row for row in report["kernels"]}
    kernels = ("pt_naive_render", "film_reduce", "simd_count_lanes", "simd_count_packed",
               "simd_count_two_steps", "simd_count_turns")   # counters on: their sums
    assert set(rows) == {(t, k) for t in ("nvptx64", "amdgcn") for k in kernels} \
        | {("amdgcn", "film_accumulate"), ("amdgcn", "film_accumulate_pass")}   # the device film: the MI210 model has float64
    for (target, kernel), row in rows.items():
        assert row["ok"] and row["error"] is None
        if target == "amdgcn" or report["ptxas"]:     # without ptxas, nvptx64's figures are None
            assert row["registers"] > 0 and row["spill_bytes"] == 0 and row["stack_bytes"] >= 0, row


@pytest.mark.parametrize("argv, message", [
    (["gpucheck", "--json", "x.json"], "--json goes with --offline"),
    (["gpucheck", "--offline", "--fast"], "--fast belongs to a run on a device"),
    (["--device", "0", "gpucheck", "--offline"], "--device belongs to a run on a device"),
    (["gpucheck", "--offline", "--json", "report.txt"], "--json report.txt: give a .json name"),
])
def test_bad_options_are_one_error_line(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_without_clang_the_command_says_what_to_install(monkeypatch, capsys):
    monkeypatch.setattr(offline_build, "CLANG_NAMES", ("no-such-clang-16",))
    assert main(["gpucheck", "--offline"]) == 2
    assert "apt-get install clang-16 libclc-16" in capsys.readouterr().err
