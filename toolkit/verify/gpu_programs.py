"""Every program the host builds on a GPU, found without a GPU: what `gpucheck --offline`
(toolkit/verify/offline_build.py) hands to clang.

The host decides its defines per device (toolkit/opencl/program.py: BUILTINS_ARE_CALLS on PoCL;
toolkit/opencl/device_scene.py: NODE_WIDTH 4 where work-items are lanes; toolkit/techniques/mlt.py:
MLT_CHAIN_MAJOR on a CPU). Rather than write those rules a second time, this module runs the
host's own code: each technique and variant is constructed for each bundled scene on a stand-in
for a GPU device (a description of its properties, not an OpenCL object), and program.build
records what program.build_inputs says it would compile, instead of compiling it. So a define
that a technique adds tomorrow reaches the offline build by itself.
"""
import contextlib
import itertools
from dataclasses import dataclass, field
from types import SimpleNamespace

import pyopencl as cl

from toolkit.api import as_scene
from toolkit.core.scene import bundled_scene_dir, bundled_scene_names
from toolkit.opencl import lanes, program
from toolkit.opencl.builds import Builds
from toolkit.opencl.device_model import AMD_VENDOR_ID, NVIDIA_VENDOR_ID
from toolkit.opencl.device_scene import DeviceScene
from toolkit.opencl.device_film import DeviceFilm, has_fp64
from toolkit.opencl.film_reduce import FilmReduction
from toolkit.opencl.record_film import RecordFilm
from toolkit.opencl.simd_counters import StepLog
from toolkit.techniques import TECHNIQUES, VARIANTS, get_technique

# The GPUs the offline build compiles for, as the host would see them through OpenCL: the
# properties it reads to pick defines and work sizes. The H200 is the one of results/gpu/; the
# MI210 is a CDNA2 card (gfx90a), the AMD target of libclc's amdgcn bitcode. The H200 model lists no 64-bit
# atomics nor float64 and the MI210 both, so that each film path (record_film.cl's 32- and 64-bit
# atomics, the path tracers' host and device films) is built for one of them.
GPU_MODELS = {
    "nvidia": dict(name="NVIDIA H200 (offline model)", vendor="NVIDIA Corporation", vendor_id=NVIDIA_VENDOR_ID,
                   platform="NVIDIA CUDA", max_compute_units=132, global_mem_size=141 * 2**30,
                   max_mem_alloc_size=35 * 2**30, extensions="cl_nv_device_attribute_query",
                   compute_capability_major_nv=9, compute_capability_minor_nv=0),
    "amd": dict(name="AMD Instinct MI210 (offline model)", vendor="Advanced Micro Devices, Inc.",
                vendor_id=AMD_VENDOR_ID, platform="AMD Accelerated Parallel Processing", max_compute_units=104,
                global_mem_size=64 * 2**30, max_mem_alloc_size=48 * 2**30,
                extensions="cl_amd_device_attribute_query cl_khr_int64_base_atomics cl_khr_fp64", simd_per_compute_unit_amd=4,
                wavefront_width_amd=64),
}

# Both ways the host builds the kernels: with the SIMD counters (render's API default, compare)
# and without (the render command, bench, gpucheck's timings).
COUNT_SIMD = (True, False)


@dataclass
class HostBuild:
    """One program as the host would build it on the GPU: cl/<name>, the source with its includes
    inlined, the compiler options, and which renders build it ("scene technique counters")."""
    name: str
    source: str
    options: list
    local_size: int
    uses: list = field(default_factory=list)


def stand_in_device(vendor):
    """A GPU device of GPU_MODELS as the host code reads one (pyopencl's attribute names)."""
    model = dict(GPU_MODELS[vendor])
    platform = SimpleNamespace(name=model.pop("platform"))
    return SimpleNamespace(type=cl.device_type.GPU, platform=platform, max_work_group_size=1024,
                           native_vector_width_float=1, driver_version="offline", **model)


class _StandIn:
    """What pyopencl's Buffer and Kernel give the constructors while recording: nothing to use."""
    _handles = itertools.count(1)

    def __init__(self, *args, **kwargs):
        self.int_ptr = next(self._handles)

    def __getattr__(self, name):   # a recorded program's kernels (program.kernel looks them up so)
        return _StandIn()


@contextlib.contextmanager
def _recording(device, builds):
    """Within: program.build records (into `builds`, by name, source and options) and compiles
    nothing. The constructors also upload the scene (cl.Buffer) and look up kernels (cl.Kernel):
    with no OpenCL device those get stand-ins. Any other pyopencl call fails, naming itself."""
    def record(queue, name, defines=None, directory=None, arg_info=False, binary_cache=True):
        source, options = program.build_inputs(queue, name, defines, directory, arg_info)
        local_size = dict(defines or {}).get("LOCAL_SIZE", program.LOCAL_SIZE)
        build = builds.setdefault((name, source, tuple(options)), HostBuild(name, source, options, local_size))
        build.uses.append(current_use[0])
        built = _StandIn()
        built.kernels_by_name, built.vector_widths = {}, {}   # what program.kernel reads of a built program
        return built

    current_use = [""]
    saved = program.build, cl.Buffer, cl.Kernel
    program.build, cl.Buffer, cl.Kernel = record, _StandIn, _StandIn
    try:
        yield current_use
    finally:
        program.build, cl.Buffer, cl.Kernel = saved


def host_builds(vendor, scenes=None, techniques=None, counters=COUNT_SIMD):
    """[HostBuild] of every program that rendering each technique and variant (`techniques`:
    default all) on each bundled scene (`scenes`: default all), with the SIMD counters on and
    off (`counters`), builds on the `vendor` GPU of GPU_MODELS, each program once, in the order
    first built."""
    device = stand_in_device(vendor)
    context = SimpleNamespace(devices=[device], int_ptr=0)
    queue = SimpleNamespace(device=device, context=context, builds=Builds(lanes.setting_for(device)))
    builds = {}
    with _recording(device, builds) as current_use:
        for scene_name in scenes or bundled_scene_names():
            device_scene = DeviceScene(queue, as_scene(bundled_scene_dir(scene_name)))
            for technique in techniques or [*TECHNIQUES, *VARIANTS]:
                cls, options = get_technique(technique)
                for count_simd in counters:
                    current_use[0] = f"{scene_name} {technique}" + ("" if count_simd else " (no counters)")
                    try:
                        tech = cls(queue, device_scene, count_simd=count_simd, **options)
                        if tech.family == "pt":   # the path tracers' collect builds it at the first pass
                            FilmReduction(queue, tech.local_size)
                            if has_fp64(device):   # and, where the device has float64, its film
                                program.build(queue, DeviceFilm.source, DeviceFilm.defines(tech.local_size))
                        if tech.family == "bdpt":   # BDPT's first pass builds its film
                            RecordFilm(queue, 1, tech.local_size)
                        if count_simd:   # the first counted step builds the counters' sums
                            StepLog(queue, tech.warp_width, tech.local_size)
                    except (AttributeError, TypeError) as error:
                        raise RuntimeError(f"recording the programs of {current_use[0]} without a device failed: "
                                           f"its host code now calls OpenCL at construction ({error}); give "
                                           "toolkit/verify/gpu_programs.py a stand-in for that call") from error
    return list(builds.values())
