"""`python -m toolkit devices`: the OpenCL platforms and devices, what each one is and which one
the toolkit picks."""
import os

import pyopencl as cl

from toolkit.opencl import runtimes
from toolkit.opencl.device import (HOW_TO_GET_OPENCL, RANKING, NoOpenCLError, candidates, describe, has_gpu,
                                   pick_device, probe_note)
from toolkit.opencl.device_model import device_warp_width
from toolkit.opencl.work_sizes import device_work_sizes


def add_command(sub):
    p = sub.add_parser("devices", help="list OpenCL platforms and devices, and which one the toolkit picks")
    p.set_defaults(run=cmd_devices)


def cmd_devices(args):
    print(devices_report())
    return 0


def devices_report():
    """Text for `python -m toolkit devices`."""
    found = candidates()
    if not found:
        return HOW_TO_GET_OPENCL
    lines = ["OpenCL devices, best first (select with --device P:D or PYOPENCL_CTX=P:D):"]
    for c in found:
        lines += _device_lines(c)
    lines.append("Ranking of usable devices: " + " > ".join(RANKING))
    try:
        _, device = pick_device()
        lines.append(f"The toolkit would pick: {describe(device)}")
    except NoOpenCLError as error:
        lines.append(f"The toolkit cannot pick a device: {error}")
    return "\n".join(lines + _environment_lines())


def _device_lines(c):
    """What one candidate device is: its selector, whether it is usable, its sizes and SIMD width."""
    state = "usable" if c.usable else f"NOT usable: {c.reason}"
    width, why = device_warp_width(c.device)
    return [f"  {c.selector}  {c.device.name.strip()}  [{state}]",
            f"       implementation: {c.implementation}, compiler: {c.compiler}",
            f"       platform: {c.platform.name.strip()} {c.platform.version.strip()}",
            f"       type: {cl.device_type.to_string(c.device.type)}, compute units: "
            f"{c.device.max_compute_units}, max work-group: {c.device.max_work_group_size}, "
            f"global memory: {c.device.global_mem_size / 2**30:.1f} GiB",
            f"       SIMD counters: warps of {width} ({why}; --warp-width overrides)",
            f"       in flight: {device_work_sizes(c.device).text()}; options stream_size / pool_size override"] + \
        ([f"       probe: {probe_note(c.device)}"] if probe_note(c.device) else [])


def _environment_lines():
    """The environment variables and registered runtimes that change what the list shows."""
    lines = []
    for variable in ("PYOPENCL_CTX", "TOOLKIT_HIDE_PLATFORMS"):
        if os.environ.get(variable):
            lines.append(f"({variable}={os.environ[variable]} is set)")
    if runtimes.registered_vendors:
        lines.append(f"Intel's CPU runtime from pip is registered beside the system's drivers "
                     f"(OCL_ICD_VENDORS={runtimes.registered_vendors})"
                     + "".join(f"; passed over: {why}" for why in runtimes.vendors_refused) + ".")
    elif runtimes.vendors_refused:
        lines.append("Intel's CPU runtime from pip is NOT registered: no vendors folder that only this user can "
                     "write (" + "; ".join(runtimes.vendors_refused) + ").")
    elif os.environ.get("OCL_ICD_VENDORS"):
        lines.append(f"(OCL_ICD_VENDORS={os.environ['OCL_ICD_VENDORS']} is set: the toolkit registers no runtime)")
    if not has_gpu():
        lines.append("No GPU found: kernels run on the CPU, where idle SIMD lanes cost less than "
                     "on a GPU; the SIMD-efficiency counters still model a GPU warp (of 32).")
    return lines
