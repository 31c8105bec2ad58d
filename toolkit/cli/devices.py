"""`python -m toolkit devices`: the OpenCL platforms and devices, what each one is and which one
the toolkit picks."""

import pyopencl as cl

from toolkit.core.config import config
from toolkit.core.validate import InputError
from toolkit.opencl import lanes, program, runtimes
from toolkit.opencl.device import (RANKING, NoOpenCLError, candidates, choose, describe, get_queue, has_gpu,
                                   pick_device, probe_note)
from toolkit.opencl.install_advice import how_to_get_opencl
from toolkit.opencl.record_film import film_path
from toolkit.opencl.device_film import film_path as path_tracers_film_path
from toolkit.opencl.device_model import device_warp_width, is_gpu
from toolkit.opencl.work_sizes import device_work_sizes


def add_command(sub):
    p = sub.add_parser("devices", help="list OpenCL platforms and devices, and which one the toolkit picks")
    p.set_defaults(run=cmd_devices)


def cmd_devices(args):
    print(devices_report())
    return 0


def devices_report():
    """Text for `python -m toolkit devices`. NoOpenCLError, saying what to install on this system,
    where no OpenCL platform is found (the command then exits with 2, like every other)."""
    found = candidates()
    if not found:
        raise NoOpenCLError(how_to_get_opencl())
    lines = ["OpenCL devices, best first (select with --device P:D or PYOPENCL_CTX=P:D):"]
    for c in found:
        lines += _device_lines(c)
    lines.append("Ranking of usable devices: " + " > ".join(RANKING))
    try:
        chosen, why = choose(found) if not config().pyopencl_ctx else _selected(found)
        lines.append(f"The toolkit would pick: {describe(chosen.device)}")
        lines.append(f"  why: {why}")
    except NoOpenCLError as error:
        lines.append(f"The toolkit cannot pick a device: {error}")
    return "\n".join(lines + _environment_lines())


def _selected(found):
    """(the device PYOPENCL_CTX selects, why)."""
    _, device = pick_device()
    chosen = next(c for c in found if c.device.int_ptr == device.int_ptr)
    return chosen, f"PYOPENCL_CTX={config().pyopencl_ctx} selects it"


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
            *_lanes_lines(c),
            f"       SIMD counters: warps of {width} ({why}; --warp-width overrides)",
            f"       in flight: {device_work_sizes(c.device).text()}; options stream_size / pool_size override",
            f"       BDPT's film (connection records summed per pixel on the device): {film_path(c.device)}",
            f"       path tracers' film (each pass's sums per pixel): {path_tracers_film_path(c.device)}"] + \
        ([f"       probe: {probe_note(c.device)}"] if probe_note(c.device) else [])


def _lanes_lines(c):
    """Whether the device runs work-items as SIMD lanes (toolkit/opencl/lanes.py): on Intel's CPU
    runtime the setting, and the width its compiler gives probe.cl with lanes on, from its log."""
    if not c.usable:
        return []
    if is_gpu(c.device):
        return ["       SIMD lanes: the GPU's warps (hardware)"]
    if "Oclgrind" in c.platform.name:
        return ["       SIMD lanes: none (a simulator, one work-item at a time)"]
    if not lanes.can_choose(c.device):
        return ["       SIMD lanes: none reported (its compiler may vectorize a work-group's work-item loops; "
                "its build log does not say)"]
    try:
        setting = lanes.setting_for(c.device)
    except InputError as error:   # TOOLKIT_LANES is wrong, or asks what the user's environment forbids
        return [f"       SIMD lanes: {error}"]
    fixed, variable = lanes.fixed_by_environment()
    if fixed:
        widths = program.vector_widths(program.build(get_queue(c.selector), "probe.cl"))
        return [f"       SIMD lanes: {fixed}, for the whole process ({variable} is set): its compiler runs probe.cl "
                f"{lanes.width(widths) or '?'} work-item(s) to a vector (its build log)"]
    widths = program.vector_widths(program.build(get_queue(c.selector, "on"), "probe.cl"))
    return [f"       SIMD lanes: {setting} (--lanes on|off or TOOLKIT_LANES; default {lanes.INTEL_DEFAULT}); "
            f"with lanes on its compiler runs probe.cl {lanes.width(widths) or '?'} work-items to a vector "
            "(its build log)"]


def _environment_lines():
    """The environment variables and registered runtimes that change what the list shows."""
    lines, settings, prepared = [], config(), runtimes.prepare()
    if settings.pyopencl_ctx:
        lines.append(f"(PYOPENCL_CTX={settings.pyopencl_ctx} is set)")
    if settings.hide_platforms:
        lines.append(f"(TOOLKIT_HIDE_PLATFORMS={','.join(settings.hide_platforms)} is set)")
    if prepared.registered:
        lines.append(f"Intel's CPU runtime from pip is registered beside the system's drivers "
                     f"({runtimes.registration_variable()}={prepared.registered})"
                     + "".join(f"; passed over: {why}" for why in prepared.refused) + ".")
    elif prepared.refused:
        lines.append("Intel's CPU runtime from pip is NOT registered: no vendors folder that only this user can "
                     "write (" + "; ".join(prepared.refused) + ").")
    elif prepared.users_vendors:
        lines.append(f"(OCL_ICD_VENDORS={prepared.users_vendors} is set: the toolkit registers no runtime)")
    if not has_gpu():
        lines.append("No GPU found: kernels run on the CPU, where idle SIMD lanes cost less than "
                     "on a GPU; the SIMD-efficiency counters still model a GPU warp (of 32).")
    return lines
