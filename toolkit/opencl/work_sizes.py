"""How much work the stream techniques keep in flight: the path-tracing stream size and the BDPT
sample pool, chosen from the device (issue 14, item 2).

A GPU hides memory latency by switching between resident warps, so a stream must hold at least
as many paths as the device can keep resident: compute units x resident work-items per unit.
`choose_work_sizes` takes that product from a table by vendor (RESIDENT_*, each number with its
source), and `device_work_sizes` reads the properties it needs from a pyopencl device.

A CPU keeps the sizes the project has always used (CPU_STREAM_SIZE, CPU_POOL_SIZE): PoCL runs
one work-group per core at a time, 32,768 paths give every core hundreds of groups to share,
and the figures and tests of this project were measured with them (the images do not depend
on the sizes: random numbers are keyed by sample, not by work-item).

Then the sizes must fit the device: each buffer at most CL_DEVICE_MAX_MEM_ALLOC_SIZE, the
stream and pool memory together at most a quarter of the global memory, and every element
index a kernel forms below 2^31 (the kernels index with 32-bit ints; see buffer_plan).
`check_fits` refuses, with an InputError naming the buffer, a size given by hand that breaks one
of these; the automatic choice shrinks to fit instead.
"""
import re
from dataclasses import dataclass
from types import MappingProxyType

import pyopencl as cl

from toolkit.core.layout import BDPT_SLOT, BDPT_VERTEX, LANE_COUNTS, LONGEST_SUBPATH, PATH_STATE, SHADOW_RAY, SUBPATH
from toolkit.core.validate import LIMITS, InputError, whole_number
from toolkit.opencl.device_model import device_warp_width, vendor_of
from toolkit.opencl.device_model import is_gpu as device_is_gpu

CPU_STREAM_SIZE = 1 << 15      # paths per PT stream on a CPU (the project's size since the start)
CPU_POOL_SIZE = 1 << 12        # BDPT samples in flight on a CPU
CPU_CHAINS_PER_UNIT = 1024     # mlt's chains per CPU core: CHAINS_MEASURED below
# mlt's chains. Every chain must make many mutations before its start is forgotten (startup
# bias: the talk's "many parallel samplers means lots of bias"), so there should be as few
# chains as keep the device busy. A GPU needs one per resident work-item (its pool size). On a
# CPU the lanes are few, but each iteration's ~60 launches (one per stream and walk step, ~30 steps on
# door_ajar: its longest subpath) cost a fixed time each: a CPU is full when an iteration's work hides that
# cost. CHAINS_MEASURED (results/issue40_mlt_door.md; door_ajar, 64x64, a 2-core EPYC, Intel's
# runtime): mutations/s at steady state 159k with 512 chains, 222k with 1,024, 267k with 2,048,
# 285k with 4,096, ~270k beyond: 2,048 (1,024 per core) is within 10% of the most. At equal time
# (60 s, 3 runs each) 2,048 chains had the lowest error: relative RMSE 0.123, against 0.135
# with 1,024 (variance: fewer mutations) and 0.132 with 4,096 (startup bias, z = 3.9).

# NVIDIA: maximum resident threads per SM, by compute capability (CUDA C++ Programming Guide,
# "Technical Specifications per Compute Capability", row "Maximum number of resident threads
# per SM"): 2048 for most; 1024 on Turing (7.5); 1536 on 8.6, 8.9 and 12.x. The capability
# comes from cl_nv_device_attribute_query; without it, 2048. A constant table: read-only.
NVIDIA_RESIDENT = MappingProxyType({(7, 5): 1024, (8, 6): 1536, (8, 9): 1536, (12, 0): 1536})
NVIDIA_RESIDENT_DEFAULT = 2048
# AMD GCN/CDNA: a compute unit has 4 SIMDs, each holding up to 10 wavefronts of 64 work-items
# (AMD "Graphics Core Next Architecture" whitepaper, 2012; the SIMD count and wavefront width
# come from cl_amd_device_attribute_query when the driver offers it): 4 x 10 x 64 = 2560.
AMD_WAVES_PER_SIMD = 10
# Intel GPUs: CL_DEVICE_MAX_COMPUTE_UNITS counts execution units (EUs); an EU holds 7 hardware
# threads on Gen9 .. Xe-LP and 8 on Xe-HPG (Arc) and Xe-HPC (Data Center GPU Max/Flex) (Intel's
# "oneAPI GPU Optimization Guide", Xe GPU architecture), each running SIMD-width work-items
# (the warp width W of toolkit.opencl.device_model.choose_warp_width, 16 by default).
INTEL_THREADS_PER_EU, INTEL_THREADS_PER_EU_XE_HPG = 7, 8
# Any other GPU: 2048 per compute unit, NVIDIA's figure, a guess.
OTHER_RESIDENT = 2048

ROUND = 256                    # sizes are multiples of the largest local size
INT_MAX = 2**31 - 1
MEMORY_SHARE = 4               # stream + pool memory at most global memory / MEMORY_SHARE


@dataclass(frozen=True)
class WorkSizes:
    stream_size: int     # paths in flight in pt_inplace_regen and pt_compact_regen
    pool_size: int       # samples in flight in the BDPT techniques and mlt
    why: str             # how they were chosen, for `devices`, render and compare
    chains: int = None   # mlt's chains: enough to fill the device, no more (CPU_CHAINS_PER_UNIT)

    def text(self):
        return (f"stream {self.stream_size:,} paths, BDPT pool {self.pool_size:,} samples, "
                f"mlt {self.chains:,} chains ({self.why})")


def resident_per_unit(vendor="", vendor_id=None, warp_width=32, compute_capability=None,
                      simd_per_unit=None, wavefront_width=None, name=""):
    """(work-items a GPU compute unit keeps resident, where the number comes from)."""
    kind = vendor_of(vendor, vendor_id)
    if kind == "nvidia":
        if compute_capability:
            major, minor = (int(x) for x in compute_capability)
            per = NVIDIA_RESIDENT.get((major, minor), 1536 if major == 12 else NVIDIA_RESIDENT_DEFAULT)
            return per, f"NVIDIA compute capability {major}.{minor}: {per} resident threads per SM"
        return NVIDIA_RESIDENT_DEFAULT, f"NVIDIA: {NVIDIA_RESIDENT_DEFAULT} resident threads per SM"
    if kind == "amd":
        simds = simd_per_unit if simd_per_unit and simd_per_unit > 0 else 4
        wave = wavefront_width if wavefront_width in (32, 64) else 64
        per = simds * AMD_WAVES_PER_SIMD * wave
        return per, f"AMD: {simds} SIMDs x {AMD_WAVES_PER_SIMD} wavefronts of {wave} per compute unit"
    if kind == "intel":
        threads = INTEL_THREADS_PER_EU_XE_HPG if re.search(r"\b(arc|max|flex)\b", name.lower()) else INTEL_THREADS_PER_EU
        return threads * warp_width, f"Intel GPU: {threads} threads x SIMD{warp_width} per EU"
    return OTHER_RESIDENT, f"a GPU of another vendor: {OTHER_RESIDENT} per compute unit assumed"


def choose_work_sizes(is_gpu, compute_units=1, max_alloc=None, global_memory=None, max_vertices=LONGEST_SUBPATH,
                      **vendor):
    """WorkSizes for a device described by these properties (device_work_sizes reads them):
    - a CPU: CPU_STREAM_SIZE and CPU_POOL_SIZE (module docstring), and mlt_chains;
    - a GPU: both = compute units x resident work-items per unit (resident_per_unit), rounded
      up to a multiple of 256, so every resident slot of the GPU holds a path or a sample.
    Both then shrink (halving) until the buffers fit the device (fits)."""
    if not is_gpu:
        stream, pool, why = CPU_STREAM_SIZE, CPU_POOL_SIZE, "a CPU: the project's CPU sizes"
    else:
        per, source = resident_per_unit(**vendor)
        resident = max(1, int(compute_units)) * per
        stream = pool = -(-resident // ROUND) * ROUND
        why = f"{compute_units} compute units x {per} resident ({source})"
    shrunk = False
    while stream > ROUND and problems(buffer_plan(stream_size=stream), max_alloc, global_memory):
        stream, shrunk = stream // 2, True
    while pool > ROUND and problems(buffer_plan(pool_size=pool, max_vertices=max_vertices), max_alloc, global_memory):
        pool, shrunk = pool // 2, True
    if shrunk:
        why += "; halved to fit the device's memory"
    return WorkSizes(stream, pool, why, mlt_chains(is_gpu, compute_units, pool))


def mlt_chains(is_gpu, compute_units, pool):
    """mlt's chains on a device (see CPU_CHAINS_PER_UNIT): a GPU's resident work-items (its
    pool), a CPU's cores x CPU_CHAINS_PER_UNIT; never more than the pool nor the chains' limit (LIMITS)."""
    chains = pool if is_gpu else max(1, int(compute_units)) * CPU_CHAINS_PER_UNIT
    return min(chains, pool, LIMITS["mlt.chains"][1])


def device_properties(device):
    """The properties choose_work_sizes needs, read from a pyopencl device (vendor queries only
    where the device lists their extension)."""
    is_gpu = device_is_gpu(device)
    props = dict(is_gpu=is_gpu, compute_units=device.max_compute_units, max_alloc=device.max_mem_alloc_size,
                 global_memory=device.global_mem_size, vendor=device.vendor.strip(), vendor_id=device.vendor_id,
                 name=device.name.strip(), warp_width=device_warp_width(device)[0])
    extensions = device.extensions if is_gpu else ""
    try:
        if "cl_nv_device_attribute_query" in extensions:
            props["compute_capability"] = (device.compute_capability_major_nv, device.compute_capability_minor_nv)
        if "cl_amd_device_attribute_query" in extensions:
            props["simd_per_unit"] = device.simd_per_compute_unit_amd
            props["wavefront_width"] = device.wavefront_width_amd
    except (cl.Error, AttributeError):
        pass   # a driver that lists the extension but fails the query: the vendor's default
    return props


def device_work_sizes(device, max_vertices=LONGEST_SUBPATH):
    """WorkSizes for a pyopencl device: see choose_work_sizes."""
    return choose_work_sizes(max_vertices=max_vertices, **device_properties(device))


# ---- what the sizes cost: buffers and the largest index the kernels form in them -----------

def _record_bytes():
    """Bytes per record (toolkit/core/layout.py), of each buffer the sizes pay for."""
    def soa(record):
        return sum(record.dtype[f].itemsize for f, _ in record.soa_fields)
    return {"path": soa(PATH_STATE), "shadow": soa(SHADOW_RAY), "subpath": soa(SUBPATH),
            "vertex": BDPT_VERTEX.dtype.itemsize, "slot": BDPT_SLOT.dtype.itemsize, "lanes": LANE_COUNTS.dtype.itemsize}


def buffer_plan(stream_size=0, pool_size=0, max_vertices=LONGEST_SUBPATH):
    """[(buffer, bytes, largest element index a kernel forms in it)] for a PT stream of
    `stream_size` and a BDPT pool of `pool_size` (0: not used). The indices are those of the
    kernels' 32-bit int arithmetic: a vertex is vertex_index(slot, k) = slot * MAX_VERTICES + k
    (cl/vertex_memory.h, whose word offset within the vertex memory is formed in size_t), naive
    connect's records below pool x (MAX_VERTICES + 1) (cl/bdpt_naive_connect.cl), and a parallel
    connect may list every strategy of every sample: (MAX_VERTICES + 1) x MAX_VERTICES - 1 per
    sample (connection_count, cl/bdpt.h) in an int scan."""
    b = _record_bytes()
    plan = []
    if stream_size:
        plan += [("path stream", b["path"] * stream_size, stream_size - 1),
                 ("shadow-ray queue", b["shadow"] * stream_size, stream_size - 1)]
    if pool_size:
        vertices = pool_size * max_vertices
        strategies = pool_size * ((max_vertices + 1) * max_vertices - 1)
        plan += [("BDPT vertex memory (per subpath stream)", b["vertex"] * vertices, vertices - 1),
                 ("BDPT subpath stream", b["subpath"] * pool_size, pool_size - 1),
                 ("naive connect records", 16 * pool_size * (max_vertices + 1), pool_size * (max_vertices + 1) - 1),
                 ("parallel connect strategies (int scan)", 0, strategies - 1)]
    return plan


def problems(plan, max_alloc=None, global_memory=None):
    """What is wrong with a buffer plan on a device with these limits: [] when it fits."""
    found = []
    for name, size, index in plan:
        if index > INT_MAX:
            found.append(f"{name}: index {index:,}, above the 32-bit int kernels' 2^31 - 1")
        if max_alloc and size > max_alloc:
            found.append(f"{name}: {size / 2**20:,.0f} MiB, above the device's largest buffer "
                         f"(CL_DEVICE_MAX_MEM_ALLOC_SIZE {max_alloc / 2**20:,.0f} MiB)")
    total = sum(size for _, size, _ in plan) * 2    # two of each stream (compaction), two vertex memories
    if global_memory and total > global_memory // MEMORY_SHARE:
        found.append(f"all its buffers: about {total / 2**20:,.0f} MiB, above a quarter of the device's "
                     f"{global_memory / 2**30:.1f} GiB")
    return found


def checked_size(option, size):
    """`size` of option "stream_size" or "pool_size" if None or a whole number in its LIMITS range."""
    return size if size is None else whole_number(f"technique.{option}", size, option)


def check_fits(device, option, size, max_vertices=LONGEST_SUBPATH):
    """`size` for option "stream_size" or "pool_size", checked: a whole number in its LIMITS range
    whose buffers the device can allocate and whose indices fit an int; else an InputError."""
    size = whole_number(f"technique.{option}", size, option)
    plan = buffer_plan(**{option: size}, max_vertices=max_vertices)
    found = problems(plan, device.max_mem_alloc_size, device.global_mem_size)
    if found:
        raise InputError(f"{option} {size:,} does not fit this device: {'; '.join(found)}. "
                         f"Give a smaller {option} (the device's own choice: `python -m toolkit devices`)")
    return size
