"""What to install for OpenCL, per system: the message when no OpenCL platform is found, and the
fixes when no device can build the kernels. Pure functions of the system and the machine
(platform.system(), platform.machine()), so that each system's advice is tested on any machine.

What `pip install .` brings (setup.cfg): on Linux x86-64 PoCL and Intel's CPU runtime, on x86-64
Windows Intel's CPU runtime, on macOS nothing, since pyopencl's wheel uses Apple's OpenCL (its CPU
and GPU devices). ARM Linux gets no OpenCL from pip: its distribution's PoCL is the CPU device.
docs/getting_started.md says the same, per system.
"""
import platform

GPU_DRIVER = "your GPU vendor's OpenCL driver (NVIDIA's, AMD's and Intel's GPU drivers include it)"


def system_name(system, machine):
    """"ARM Linux", "x86-64 Windows", ... as a learner would name the machine."""
    arm = machine.lower() in ("aarch64", "arm64") or machine.lower().startswith("arm")
    if system == "Darwin":
        return "macOS"
    if system == "Linux":
        return "x86-64 Linux" if machine == "x86_64" else "ARM Linux" if arm else f"{machine} Linux"
    if system == "Windows":
        return "Windows on ARM" if arm else "x86-64 Windows" if machine in ("AMD64", "x86_64") else "Windows"
    return f"{system} ({machine})"


def install_lines(system, machine):
    """The ways to get an OpenCL device on this system, best first, one a line."""
    name = system_name(system, machine)
    if name == "macOS":
        return ["macOS has OpenCL (Apple's, for the CPU and the GPU); pyopencl's wheel uses it. Reinstall "
                "pyopencl from its wheel: pip install --force-reinstall --only-binary=:all: pyopencl"]
    if name == "x86-64 Linux":
        return ["pip install pocl-binary-distribution   (PoCL, the CPU; `pip install .` brings it)",
                "pip install intel-opencl-rt intel-cmplr-lib-rt   (Intel's CPU runtime; the toolkit registers it)",
                "a distribution's PoCL, e.g. sudo apt-get install pocl-opencl-icd",
                GPU_DRIVER]
    if system == "Linux":
        return ["sudo apt-get install pocl-opencl-icd   (PoCL, the CPU: Debian, Ubuntu, Raspberry Pi OS; "
                "Fedora: sudo dnf install pocl); pip has no CPU OpenCL for this machine",
                "or conda's: conda install -c conda-forge pyopencl pocl",
                GPU_DRIVER]
    if name == "x86-64 Windows":
        return [GPU_DRIVER,
                "pip install intel-opencl-rt intel-cmplr-lib-rt   (Intel's CPU runtime, any x86-64 CPU; "
                "`pip install .` brings it, the toolkit registers it)"]
    if system == "Windows":
        return [GPU_DRIVER,
                "Microsoft's \"OpenCL and OpenGL Compatibility Pack\" (Microsoft Store): OpenCL on a DirectX 12 GPU"]
    return ["an OpenCL implementation for this system: PoCL (https://portablecl.org) for the CPU", GPU_DRIVER]


def how_to_get_opencl(system=None, machine=None):
    """The message when no OpenCL platform is found (`devices` and every command, exit 2)."""
    system, machine = system or platform.system(), machine or platform.machine()
    return (f"No OpenCL platform was found. To get one on {system_name(system, machine)}:\n"
            + "\n".join(f"  - {line}" for line in install_lines(system, machine))
            + "\nthen run `python -m toolkit devices`.")


def fixes_when_nothing_builds(intel_installed, system=None, machine=None):
    """The fixes to list when devices exist but none can build the kernels (those already
    installed left out)."""
    system, machine = system or platform.system(), machine or platform.machine()
    lines = install_lines(system, machine)
    if system == "Linux" and machine == "x86_64":
        lines = lines[1:]        # PoCL from pip is there (it is what failed, or hidden)
    if intel_installed:
        lines = [line for line in lines if "intel-opencl-rt" not in line]
    return lines
