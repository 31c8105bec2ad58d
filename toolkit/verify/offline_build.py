"""`python -m toolkit gpucheck --offline`: every kernel of every technique and variant, built for
two GPUs on a machine that has neither, by clang's OpenCL front end with libclc (Debian:
`apt-get install clang-16 libclc-16`). A kernel that builds here builds for the GPUs' own
compilers in all likelihood (NVIDIA's and AMD's OpenCL are LLVM too), and what the compilers
report per kernel says what a GPU would pay for it: registers, spills, stack, shared memory.

- NVIDIA: clang writes PTX for sm_90 (Hopper: H100, H200); `ptxas -v`, where found (on PATH,
  in a CUDA toolkit, or in PyPI's nvidia-cuda-nvcc wheel), assembles it and reports each kernel.
  In OpenCL mode clang ignores `-mcpu=sm_90` and writes `.target sm_30`: the target CPU is
  given to its front end itself (`-Xclang -target-cpu -Xclang sm_90`), and the PTX is checked.
- AMD: clang writes amdgcn assembly for gfx90a (CDNA2: MI210, MI250) with libclc's amdhsa
  bitcode as its built-in library (`-nogpulib`: not ROCm's device libraries, which Debian's
  clang does not have); the assembly's metadata names each kernel's registers and scratch.

What is built is what the host builds on a GPU (toolkit/verify/gpu_programs.py records it from
the host's own code): the same sources and options, for each bundled scene, with and without
the SIMD counters.
"""
import os
import re
import shutil
import subprocess
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from importlib.util import find_spec
from pathlib import Path

from toolkit.core.validate import InputError
from toolkit.verify.gpu_compiler_reports import amdgcn_kernels, ptx_entries, ptx_target, ptxas_kernels
from toolkit.verify.gpu_occupancy import warps_per_sm
from toolkit.verify.gpu_programs import COUNT_SIMD, host_builds


@dataclass(frozen=True)
class Target:
    key: str          # "nvptx64" or "amdgcn": the name in the JSON
    vendor: str       # the GPU model of gpu_programs.GPU_MODELS whose builds it compiles
    label: str
    clang: tuple      # clang's options for it
    libclc: str       # the libclc bitcode of its built-in functions
    arch: str         # what the output must be for


# The extensions a GPU's driver reports that the kernels use (64-bit atomics: cl/record_film.cl),
# which clang enables for these targets only when told. libclc has no 64-bit atom_add for nvptx64
# (NVIDIA's driver has), so the NVIDIA model builds record_film.cl's 32-bit path
# (gpu_programs.GPU_MODELS) and the AMD one its 64-bit path: each path built for one GPU.
GPU_EXTENSIONS = ("-Xclang", "-cl-ext=+cl_khr_int64_base_atomics")

TARGETS = (
    Target("nvptx64", "nvidia", "NVIDIA sm_90 (nvptx64)",
           ("-target", "nvptx64-nvidia-nvcl", "-Xclang", "-target-cpu", "-Xclang", "sm_90"),
           "nvptx64--nvidiacl.bc", "sm_90"),
    Target("amdgcn", "amd", "AMD gfx90a (amdgcn)",
           ("-target", "amdgcn-amd-amdhsa", "-mcpu=gfx90a", "-nogpulib", *GPU_EXTENSIONS), "amdgcn--amdhsa.bc",
           "gfx90a"),
)

# The compilers tried, newest libclc first; Debian's clang-16 and libclc-16 are what .ci/run installs.
CLANG_NAMES = ("clang-16", "clang")
LIBCLC_FOLDERS = ("/usr/lib/clc", "/usr/lib/llvm-16/lib/clc", "/usr/share/clc", "/usr/local/lib/clc")
INSTALL_HINT = "on Debian or Ubuntu: apt-get install clang-16 libclc-16"
CUDA_PTXAS = Path("/usr/local/cuda/bin/ptxas")


@dataclass
class Toolchain:
    clang: str
    clang_version: str
    libclc: Path
    ptxas: str = None          # None: the PTX is checked, not assembled
    ptxas_version: str = None


def _output(command):
    """What a tool prints (its version), or "" if it does not run."""
    try:
        result = subprocess.run(command, capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return ""
    return result.stdout + result.stderr


def find_ptxas():
    """NVIDIA's PTX assembler: on PATH, in CUDA's usual folder, or in PyPI's nvidia-cuda-nvcc
    wheel (nvidia/cu13/bin, nvidia/cuda_nvcc/bin); None where there is none."""
    if found := shutil.which("ptxas") or (str(CUDA_PTXAS) if CUDA_PTXAS.is_file() else None):
        return found
    spec = find_spec("nvidia")
    for folder in (spec.submodule_search_locations or []) if spec else []:
        for candidate in sorted(Path(folder).glob("*/bin/ptxas")):
            if os.access(candidate, os.X_OK):
                return str(candidate)
    return None


def find_toolchain():
    """The Toolchain here; InputError (saying what is missing and how to install it) without
    clang or libclc."""
    clang = next((found for name in CLANG_NAMES if (found := shutil.which(name))), None)
    if clang is None:
        raise InputError(f"no clang found (tried {', '.join(CLANG_NAMES)}): the offline GPU build needs clang's "
                         f"OpenCL front end and libclc; {INSTALL_HINT}")
    libclc = next((Path(folder) for folder in LIBCLC_FOLDERS
                   if all((Path(folder) / target.libclc).is_file() for target in TARGETS)), None)
    if libclc is None:
        raise InputError(f"libclc's bitcode ({', '.join(t.libclc for t in TARGETS)}) not found in "
                         f"{', '.join(LIBCLC_FOLDERS)}: {INSTALL_HINT}")
    ptxas = find_ptxas()
    version = re.search(r"release [\d.]+, V([\d.]+)", _output([ptxas, "--version"])) if ptxas else None
    return Toolchain(clang, (_output([clang, "--version"]).splitlines() or [""])[0], libclc, ptxas,
                     version.group(1) if version else None)


_KERNEL_IN_SOURCE = re.compile(r"\b__kernel\b[^;{]*?\bvoid\s+(\w+)\s*\(")
# clang's messages that point into our files ("bvh.h:12:5: error: ..."): the #line markers of
# toolkit/opencl/program.py name the file each line came from.
_DIAGNOSTIC = re.compile(r"^(.+?:\d+:\d+: (?:fatal )?error: .*)$", re.MULTILINE)


def _errors(log):
    """The first error lines of a compiler's log (file:line:column: error: ...), else its first lines."""
    lines = _DIAGNOSTIC.findall(log) or [line for line in log.strip().splitlines() if line.strip()]
    return "\n".join(lines[:5])


def compile_program(build, target, tools, folder):
    """[one row per kernel] for one HostBuild on one Target, its files in `folder`. Every row has
    kernel, ok, error, registers, spill_bytes, stack_bytes and shared_bytes (None where not known)
    and the target's own figures."""
    source = Path(folder) / build.name
    source.write_text(build.source)
    output = source.with_suffix(".ptx" if target.key == "nvptx64" else ".s")
    command = [tools.clang, "-x", "cl", "-cl-std=CL1.2", "-O3", *target.clang,
               "-Xclang", "-finclude-default-header",
               "-Xclang", "-mlink-builtin-bitcode", "-Xclang", str(tools.libclc / target.libclc),
               "-Wno-linker-warnings",   # libclc spells the triple its own way (nvptx64-unknown-nvidiacl): the same target
               "-S", *build.options, str(source), "-o", str(output)]
    result = _run(command)
    if result.returncode != 0:
        return _failed(build, f"clang: {_errors(result.stderr)}")
    rows = _amdgcn_rows(output.read_text()) if target.key == "amdgcn" else _nvptx_rows(build, target, tools, output)
    declared = _KERNEL_IN_SOURCE.findall(build.source)   # the tables list kernels in this order on every target
    return sorted(rows, key=lambda row: declared.index(row["kernel"]) if row["kernel"] in declared else len(declared))


def _row(kernel, ok=True, error=None, registers=None, spill_bytes=None, stack_bytes=None, shared_bytes=None, **more):
    return dict(kernel=kernel, ok=ok, error=error, registers=registers, spill_bytes=spill_bytes,
                stack_bytes=stack_bytes, shared_bytes=shared_bytes, **more)


def _nvptx_rows(build, target, tools, ptx):
    """The PTX checked (written for sm_90), then assembled by ptxas where there is one."""
    text = ptx.read_text()
    if ptx_target(text) != target.arch:
        return _failed(build, f"clang wrote PTX for {ptx_target(text)}, not {target.arch}: see {' '.join(target.clang)}")
    if tools.ptxas is None:
        return [_row(name, assembled=False) for name in ptx_entries(text)]
    result = _run([tools.ptxas, f"-arch={target.arch}", "-v", str(ptx), "-o", str(ptx.with_suffix(".cubin"))])
    if result.returncode != 0:
        return _failed(build, f"ptxas: {_errors(result.stderr)}")
    rows = []
    for name, figures in ptxas_kernels(result.stdout + result.stderr).items():
        occupancy = warps_per_sm(figures["registers"], figures["shared_bytes"], build.local_size)
        rows.append(_row(name, assembled=True, **figures, warps_per_sm=occupancy.warps,
                         occupancy_limited_by=occupancy.limited_by))
    return rows


def _amdgcn_rows(assembly):
    """The assembly's figures; in the common columns registers are VGPRs, the stack is scratch,
    and spills are the VGPRs spilled to scratch (4 bytes each per work-item; SGPRs spill into
    VGPR lanes)."""
    return [_row(name, registers=f["vgprs"], spill_bytes=4 * f["vgpr_spills"], stack_bytes=f["scratch_bytes"],
                 shared_bytes=f["lds_bytes"], **f) for name, f in amdgcn_kernels(assembly).items()]


def _run(command):
    try:
        return subprocess.run(command, capture_output=True, text=True, timeout=600)
    except subprocess.TimeoutExpired:
        return subprocess.CompletedProcess(command, 1, "", f"{command[0]} took over 600 s")


def _failed(build, error):
    """Every kernel of a program that did not build, each with the error (the program's name
    where its source names no kernel)."""
    names = _KERNEL_IN_SOURCE.findall(build.source) or [build.name]
    return [_row(name, ok=False, error=error) for name in names]


def run(scenes=None, techniques=None, counters=COUNT_SIMD, tools=None, workers=None, log=None):
    """The offline build of every program the host builds (gpu_programs.host_builds with
    `scenes`, `techniques` and `counters`) for every target, `workers` compilers at a time
    (default: one per core); returns the report (the JSON's content)."""
    tools = tools or find_toolchain()
    start = time.perf_counter()
    jobs = [(target, build) for target in TARGETS for build in host_builds(target.vendor, scenes, techniques, counters)]
    if log:
        log(f"{len(jobs)} builds ({len(jobs) // len(TARGETS)} programs x {len(TARGETS)} targets) "
            f"on {workers or os.cpu_count()} threads")

    def one(index):
        target, build = jobs[index]
        with tempfile.TemporaryDirectory(prefix="offline_build_") as folder:
            rows = compile_program(build, target, tools, folder)
        return [{"target": target.key, "program": build.name, "build": index, **row} for row in rows]

    with ThreadPoolExecutor(max_workers=workers or os.cpu_count()) as pool:
        kernels = [row for rows in pool.map(one, range(len(jobs))) for row in rows]
    # Each build's inputs once (its options and the renders that use it); each kernel row names its build.
    builds = [{"target": target.key, "program": build.name, "local_size": build.local_size,
               "options": build.options, "uses": build.uses} for target, build in jobs]
    return {"command": "python -m toolkit gpucheck --offline", "clang": tools.clang_version,
            "libclc": str(tools.libclc), "ptxas": tools.ptxas and f"{tools.ptxas} (CUDA {tools.ptxas_version})",
            "targets": {t.key: t.label for t in TARGETS}, "seconds": round(time.perf_counter() - start, 1),
            "passed": bool(kernels) and all(row["ok"] for row in kernels), "builds": builds, "kernels": kernels}
