"""Choosing the OpenCL device: a GPU when there is one, else the CPU through PoCL.

`PYOPENCL_CTX` (pyopencl's own variable, e.g. "0:0") and the `--device` option override the
automatic choice. `python -m toolkit devices` prints what is found and what would be picked.
"""
import os
from functools import lru_cache

import pyopencl as cl


class NoOpenCLError(RuntimeError):
    pass


HOW_TO_GET_OPENCL = (
    "No OpenCL platform was found. Install the CPU implementation with\n"
    "    pip install pocl-binary-distribution\n"
    "or your GPU vendor's OpenCL driver, then run `python -m toolkit devices`."
)


def list_devices():
    """All (platform_index, device_index, platform, device) tuples; [] if there is no platform."""
    try:
        platforms = cl.get_platforms()
    except cl.Error:
        return []
    found = []
    for pi, platform in enumerate(platforms):
        try:
            devices = platform.get_devices()
        except cl.Error:
            continue
        for di, device in enumerate(devices):
            found.append((pi, di, platform, device))
    return found


def _parse_selector(selector, found):
    """A selector is "P:D" (indices, like PYOPENCL_CTX), "P" or a case-insensitive substring
    of the device or platform name ("gpu" and "cpu" match the device type)."""
    selector = str(selector).strip()
    parts = selector.split(":")
    if all(p.isdigit() for p in parts if p) and parts[0]:
        pi = int(parts[0])
        di = int(parts[1]) if len(parts) > 1 and parts[1] else 0
        for entry in found:
            if entry[0] == pi and entry[1] == di:
                return entry
        raise NoOpenCLError(f"no OpenCL device {pi}:{di}; run `python -m toolkit devices`")
    needle = selector.lower()
    for entry in found:
        device = entry[3]
        kind = cl.device_type.to_string(device.type).lower()
        if needle in device.name.lower() or needle in entry[2].name.lower() or needle in kind:
            return entry
    raise NoOpenCLError(f"no OpenCL device matches {selector!r}; run `python -m toolkit devices`")


def pick_device(selector=None):
    """The (platform, device) the toolkit uses: selector, else PYOPENCL_CTX, else GPU, else CPU."""
    found = list_devices()
    if not found:
        raise NoOpenCLError(HOW_TO_GET_OPENCL)
    selector = selector or os.environ.get("PYOPENCL_CTX") or None
    if selector:
        _, _, platform, device = _parse_selector(selector, found)
        return platform, device
    gpus = [e for e in found if e[3].type & cl.device_type.GPU]
    _, _, platform, device = (gpus or found)[0]
    return platform, device


@lru_cache(maxsize=None)
def _context_for(selector):
    platform, device = pick_device(selector)
    context = cl.Context([device])
    return context, cl.CommandQueue(context)


def get_queue(selector=None):
    """One shared context and in-order queue per device choice (builds are cached per context)."""
    _, queue = _context_for(selector or os.environ.get("PYOPENCL_CTX") or None)
    return queue


def describe(device):
    return f"{device.name.strip()} ({device.platform.name.strip()}, {cl.device_type.to_string(device.type)})"


def has_gpu():
    return any(e[3].type & cl.device_type.GPU for e in list_devices())


def report():
    """Text for `python -m toolkit devices`."""
    found = list_devices()
    if not found:
        return HOW_TO_GET_OPENCL
    lines = ["OpenCL devices (select with --device P:D or PYOPENCL_CTX=P:D):"]
    for pi, di, platform, device in found:
        lines.append(f"  {pi}:{di}  {device.name.strip()}")
        lines.append(f"       platform: {platform.name.strip()} {platform.version.strip()}")
        lines.append(f"       type: {cl.device_type.to_string(device.type)}, compute units: "
                     f"{device.max_compute_units}, max work-group: {device.max_work_group_size}, "
                     f"global memory: {device.global_mem_size / 2**30:.1f} GiB")
    try:
        _, device = pick_device()
        lines.append(f"The toolkit would pick: {describe(device)}")
    except NoOpenCLError as error:
        lines.append(f"The toolkit cannot pick a device: {error}")
    if os.environ.get("PYOPENCL_CTX"):
        lines.append(f"(PYOPENCL_CTX={os.environ['PYOPENCL_CTX']} is set)")
    if not has_gpu():
        lines.append("No GPU found: kernels run on the CPU, where idle SIMD lanes cost less than "
                     "on a GPU; the SIMD-efficiency counters still model a GPU warp.")
    return "\n".join(lines)
