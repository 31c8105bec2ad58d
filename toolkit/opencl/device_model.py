"""The device model: pure functions over a device's properties (vendor, GPU or not, warp width).
The vendor IDs and the vendor matching live here once; work_sizes and the SIMD counters use them.
`device_properties` and `device_warp_width` read what they need from a pyopencl device."""
import re

import pyopencl as cl

NVIDIA_VENDOR_ID, AMD_VENDOR_ID, INTEL_VENDOR_ID = 0x10DE, 0x1002, 0x8086


def vendor_of(vendor="", vendor_id=None):
    """"nvidia", "amd", "intel" or "other", from the vendor ID or else the vendor string."""
    vendor = (vendor or "").lower()
    if vendor_id == NVIDIA_VENDOR_ID or "nvidia" in vendor:
        return "nvidia"
    if vendor_id == AMD_VENDOR_ID or "advanced micro devices" in vendor or re.search(r"\bamd\b", vendor):
        return "amd"
    if vendor_id == INTEL_VENDOR_ID or "intel" in vendor:
        return "intel"
    return "other"


def is_gpu(device):
    """A real GPU never has the CPU bit; Oclgrind's simulator has both (it reports every type),
    and is never a GPU, whatever it reports."""
    return (bool(device.type & cl.device_type.GPU) and not device.type & cl.device_type.CPU
            and "Oclgrind" not in device.platform.name)


def choose_warp_width(is_gpu, vendor="", vendor_id=None, wavefront_width=None, sub_group_sizes=()):
    """(W, why): the warp width the SIMD-efficiency counters (toolkit/core/simd.py) use by default on
    a device described by these properties (device_warp_width reads them from a device):
    - a CPU (or any non-GPU device): 32. The counters model a GPU there; a CPU's own vector
      width (4 to 16 floats) would say little about how the kernels would fare on a GPU;
    - NVIDIA: 32, the warp;
    - AMD: the wavefront width the driver reports (cl_amd_device_attribute_query), else 64
      (GCN and CDNA run wavefronts of 64; RDNA can run 32);
    - Intel: 16, the SIMD width Intel's compiler gives most kernels (one hardware thread runs 16
      work-items in lock step); where the device lists its sub-group sizes
      (cl_intel_required_subgroup_size) and 16 is not among them, the smallest listed one;
    - any other GPU: 32."""
    if not is_gpu:
        return 32, "a CPU: the counters model a GPU warp of 32"
    kind = vendor_of(vendor, vendor_id)
    if kind == "nvidia":
        return 32, "NVIDIA warp"
    if kind == "amd":
        if wavefront_width in (32, 64):
            return int(wavefront_width), "AMD wavefront, as the driver reports it"
        return 64, "AMD wavefront (GCN/CDNA)"
    if kind == "intel":
        sizes = sorted(int(s) for s in (sub_group_sizes or ()) if int(s) > 0)
        if sizes and 16 not in sizes:
            return sizes[0], "Intel GPU: its smallest sub-group size"
        return 16, "Intel GPU: SIMD16, the width its compiler gives most kernels"
    return 32, "a GPU of another vendor: 32 assumed"


def device_warp_width(device):
    """(W, why) for a pyopencl device: see choose_warp_width."""
    gpu = is_gpu(device)
    vendor = device.vendor.strip()
    vendor_id = device.vendor_id
    wavefront = sub_groups = None
    extensions = device.extensions
    if gpu and "cl_amd_device_attribute_query" in extensions:
        try:
            wavefront = device.wavefront_width_amd
        except (cl.Error, AttributeError):
            pass
    if gpu and "cl_intel_required_subgroup_size" in extensions:
        try:
            sub_groups = device.sub_group_sizes_intel
        except (cl.Error, AttributeError):
            pass
    return choose_warp_width(gpu, vendor, vendor_id, wavefront, sub_groups or ())


def resolve_warp_width(warp_width, device):
    """(W, why): `warp_width` as given, or (None) the device's default (device_warp_width)."""
    if warp_width is not None:
        return warp_width, "given"
    return device_warp_width(device)
