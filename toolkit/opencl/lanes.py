"""SIMD lanes on a CPU: whether a kernel's work-items run side by side, one per lane of a vector
register, as a GPU runs a warp; and how many.

Intel's CPU runtime can compile a kernel that way: 8 work-items in one AVX2 register, 16 with
AVX-512. Its build log says, kernel by kernel, what it did (`Kernel "extend_in_place" was
successfully vectorized (8)`, or `was not vectorized`), and that is where the width the toolkit
reports comes from (vector_widths), never from a guess.

How it is chosen. Intel's switch, the environment variable CL_CONFIG_USE_VECTORIZER, is read
once, when the runtime loads: set later in the process it changes nothing (measured). Per
build instead, the runtime's extension cl_intel_vec_len_hint takes a kernel attribute,
intel_vec_len_hint(1), that keeps that kernel scalar, or intel_vec_len_hint(W), that asks for W
lanes. Without it the compiler decides, and its cost model may keep a kernel scalar: on a 2-core
AVX2 EPYC it kept every tracing kernel scalar (57 gathers and 17 scatters in pt_naive_render,
"was not vectorized"), where another machine's run had vectorized them, so "on" meant nothing
there. So the toolkit puts the attribute on every kernel of a build (source_prefix): W = 1 with
lanes off, W = the device's native float vector width with lanes on (8 with AVX2, 16 with
AVX-512). The width reported is still the one in the log. Both settings work in one process,
each in an OpenCL context of its own (toolkit.opencl.device.get_queue). If you set CL_CONFIG_USE_VECTORIZER=False or
CL_CONFIG_CPU_VECTORIZER_MODE yourself, you fix the choice for the whole process, and asking for
the other one is an error.

The choice: `--lanes on|off` (render, compare, bench), render(lanes=...), or the environment
variable TOOLKIT_LANES=on|off, the default wherever the implementation lets the toolkit choose
(an explicit choice that a device cannot follow is an error). Unset, lanes are off on Intel's
runtime: its vectorized code is slower on our kernels today (issue 22's figures: pt_naive 3-5x).
A GPU always runs warps (`hardware`); PoCL's compiler decides by itself and its build log does not
say whether it vectorized a kernel's work-items, so there the toolkit reports no lanes.

To see what the vectorizer did, build with VOLCANO_STATS=All in the environment: the build log
then counts, per kernel, the gathers and scatters it needed (a remark "Kernel was 8-way vectorized"
followed by the two counts); CL_CONFIG_DUMP_ASM=True writes the generated code to the working folder.
AVX2 has gathers but no scatters: a store whose address differs between lanes becomes a test,
a branch and a store per lane (why cl/bvh.h pushes its stack without branches).
"""
import re

from toolkit.core.config import LANES, checked_lanes, config
from toolkit.core.validate import InputError
from toolkit.opencl.device_model import is_gpu

SETTINGS = LANES          # "on", "off": the values TOOLKIT_LANES and every lanes option take
INTEL_DEFAULT = "off"     # measured slower with lanes on (see the module docstring)
HARDWARE = "hardware"     # a GPU: its warps, not the toolkit's choice

# Ahead of the source of every build with lanes off on Intel's runtime: every kernel gets
# intel_vec_len_hint(1). `kernel` is a reserved word of OpenCL C, so defining it renames nothing.
LANES_OFF_PREFIX = ("/* lanes off (toolkit/opencl/lanes.py): each work-item stays a thread of its own */\n"
                    "#define __kernel __kernel __attribute__((intel_vec_len_hint(1)))\n"
                    "#define kernel __kernel\n")

# With lanes on: every kernel asks for `width` lanes, the device's native float vector width.
LANES_ON_PREFIX = ("/* lanes on (toolkit/opencl/lanes.py): work-items as the {width} lanes of a vector register */\n"
                   "#define __kernel __kernel __attribute__((intel_vec_len_hint({width})))\n"
                   "#define kernel __kernel\n")

_VECTORIZED = re.compile(r'Kernel "(\w+)" was (?:successfully vectorized \((\d+)\)|not vectorized)')


def preferred():
    """The TOOLKIT_LANES environment setting, or None (toolkit/core/config.py)."""
    return config().lanes


def can_choose(device):
    """Whether the toolkit can turn lanes on and off on this device: Intel's CPU runtime."""
    return "Intel" in device.platform.name and not is_gpu(device) and "Oclgrind" not in device.platform.name


def fixed_by_environment():
    """("on"/"off", the variable) where the user's environment fixes Intel's vectorizer for the
    process, else (None, None)."""
    mode = config().intel_vectorizer_mode
    if mode:
        return ("off" if mode.strip() == "1" else "on"), f"CL_CONFIG_CPU_VECTORIZER_MODE={mode}"
    use = config().intel_use_vectorizer
    if use is not None and use.strip().lower() in ("false", "0", "no", "off"):
        return "off", f"CL_CONFIG_USE_VECTORIZER={use}"
    return None, None


def setting_for(device, asked=None):
    """What a build on `device` gets: "on" or "off" (Intel's CPU runtime), HARDWARE (a GPU) or
    None (the implementation decides and does not say). `asked`: an explicit choice, which the
    device must be able to follow; TOOLKIT_LANES applies where the toolkit can choose."""
    asked = checked_lanes(asked)
    if can_choose(device):
        wanted = asked or preferred()
        fixed, variable = fixed_by_environment()
        if fixed and wanted and wanted != fixed:
            raise InputError(f"lanes {wanted} cannot be had: {variable} is set, which fixes Intel's vectorizer "
                             f"{fixed} for the whole process (the runtime reads it once, when it loads); unset it, "
                             "and the toolkit chooses lanes per build")
        return wanted or fixed or INTEL_DEFAULT
    if is_gpu(device):
        if asked == "off":
            raise InputError("a GPU always runs work-items as the lanes of its warps: --lanes off applies to "
                             "Intel's CPU runtime (--device intel)")
        return HARDWARE
    if asked == "on":
        raise InputError(f"{device.platform.name.strip()} cannot be asked to run work-items as SIMD lanes: "
                         "--lanes on needs Intel's CPU runtime (--device intel)")
    return None


def source_prefix(setting, width=None):
    """What goes ahead of a program's source for this setting (LANES_OFF_PREFIX, or LANES_ON_PREFIX
    for `width` lanes: the device's native float vector width); nothing where the user's
    environment fixes the vectorizer (the attribute would conflict with it)."""
    if fixed_by_environment()[0]:
        return ""
    if setting == "off":
        return LANES_OFF_PREFIX
    if setting == "on" and width and width > 1:
        return LANES_ON_PREFIX.format(width=width)
    return ""


def vector_widths(log):
    """{kernel: how many work-items per vector} from Intel's build log (1: not vectorized); {}
    when the log names none (other compilers)."""
    return {name: int(width) if width else 1 for name, width in _VECTORIZED.findall(log or "")}


def width(widths):
    """The widest vector a build used (1: none vectorized), or None when no log named any."""
    return max(widths.values()) if widths else None


def describe(setting, widths=None):
    """One line for reports: the setting and what the compiler did with it."""
    if setting == HARDWARE:
        return "lanes: the GPU's warps (hardware)"
    if setting is None:
        return "lanes: none reported (this compiler does not say whether it vectorizes work-items)"
    if not widths:
        return f"lanes {setting}"
    vectorized = sorted(name for name, w in widths.items() if w > 1)
    if not vectorized:
        return f"lanes {setting}: no kernel vectorized (the compiler's log, {len(widths)} kernels)"
    scalar = sorted(set(widths) - set(vectorized))
    return (f"lanes {setting}: {width(widths)} work-items per vector in {len(vectorized)} of {len(widths)} "
            "kernels (the compiler's log)" + (f"; scalar: {', '.join(scalar)}" if scalar else ""))
