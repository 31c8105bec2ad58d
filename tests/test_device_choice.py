"""The device the toolkit picks on the learners' machines, and why (issue 37), on made-up
platforms: a Mac (Apple's CPU and GPU devices), a Windows laptop with an NVIDIA GPU and Intel's
CPU runtime, a Linux desktop with an AMD GPU, and a machine with no OpenCL at all. Each case
checks the reason `python -m toolkit devices` prints: it names the device and the cause."""
from types import SimpleNamespace

import pyopencl as cl
import pytest

from toolkit.cli import devices as devices_command
from toolkit.opencl import device
from toolkit.opencl.install_advice import fixes_when_nothing_builds, how_to_get_opencl

GPU, CPU = cl.device_type.GPU, cl.device_type.CPU


def _platform(name, version, *devices):
    """[(platform_index placeholder, device)] of one made-up platform: devices are (name, type, driver)."""
    platform = SimpleNamespace(name=name, version=version)
    return [(platform, SimpleNamespace(name=n, type=kind, driver_version=driver, platform=platform))
            for n, kind, driver in devices]


APPLE = _platform("Apple", "OpenCL 1.2 (Apr 18 2024 20:11:51)",
                  ("Intel(R) Core(TM) i7-1068NG7 CPU @ 2.30GHz", CPU, "1.1"),
                  ("Intel(R) Iris(TM) Plus Graphics", GPU, "1.2(Apr 18 2024 20:11:51)"))
NVIDIA = _platform("NVIDIA CUDA", "OpenCL 3.0 CUDA 12.4.131", ("NVIDIA GeForce RTX 3060 Laptop GPU", GPU, "551.86"))
INTEL_CPU = _platform("Intel(R) OpenCL", "OpenCL 3.0 WINDOWS",
                      ("11th Gen Intel(R) Core(TM) i7-11800H @ 2.30GHz", CPU, "2025.19.3.0.17_230222"))
AMD = _platform("AMD Accelerated Parallel Processing", "OpenCL 2.1 AMD-APP (3614.0)",
                ("gfx1030", GPU, "3614.0 (PAL,LC)"))


def _machine(monkeypatch, verdicts, *platforms):
    """Make these platforms the machine's, each device's probe answering `verdicts[name]`
    ((usable, reason); usable when absent)."""
    found = [(pi, di, platform, d) for pi, devices in enumerate(platforms)
             for di, (platform, d) in enumerate(devices)]
    monkeypatch.setattr(device, "list_devices", lambda: found)
    monkeypatch.setattr(device, "probe", lambda d: verdicts.get(d.name, (True, "")))
    monkeypatch.delenv("PYOPENCL_CTX", raising=False)
    monkeypatch.delenv("TOOLKIT_HIDE_PLATFORMS", raising=False)


def _choice(monkeypatch, verdicts, *platforms):
    _machine(monkeypatch, verdicts, *platforms)
    chosen, why = device.choose(device.candidates())
    return chosen.device.name, why


def test_a_mac_picks_apples_gpu(monkeypatch):
    name, why = _choice(monkeypatch, {}, APPLE)
    assert name == "Intel(R) Iris(TM) Plus Graphics"
    assert why.startswith("Intel(R) Iris(TM) Plus Graphics (Apple ") and "is a GPU and passed the probe" in why


def test_a_mac_whose_gpu_fails_the_probe_picks_its_cpu_and_says_why(monkeypatch):
    limit = ("Intel(R) Iris(TM) Plus Graphics runs kernel probe in work-groups of at most 32 work-items "
             "(its CL_KERNEL_WORK_GROUP_SIZE), and the kernel is built for 64")
    name, why = _choice(monkeypatch, {"Intel(R) Iris(TM) Plus Graphics": (False, limit)}, APPLE)
    assert name.startswith("Intel(R) Core(TM) i7")
    assert "no GPU passed the probe" in why
    assert "Intel(R) Iris(TM) Plus Graphics (Apple 1.2(Apr 18 2024 20:11:51)) failed the probe: " + limit in why


def test_nvidia_gpu_beside_intels_cpu_runtime_picks_the_gpu(monkeypatch):
    name, why = _choice(monkeypatch, {}, INTEL_CPU, NVIDIA)
    assert name == "NVIDIA GeForce RTX 3060 Laptop GPU"
    assert why == "NVIDIA GeForce RTX 3060 Laptop GPU (NVIDIA CUDA 551.86) is a GPU and passed the probe: a GPU comes first"


def test_nvidia_gpu_that_fails_the_probe_leaves_intels_cpu_runtime(monkeypatch):
    name, why = _choice(monkeypatch, {"NVIDIA GeForce RTX 3060 Laptop GPU": (
        False, "OpenCL error while probing: clEnqueueNDRangeKernel failed: OUT_OF_RESOURCES")}, NVIDIA, INTEL_CPU)
    assert name.startswith("11th Gen Intel(R) Core(TM) i7")
    assert "no GPU passed the probe, and Intel's CPU runtime comes next in the ranking" in why
    assert "NVIDIA GeForce RTX 3060 Laptop GPU (NVIDIA CUDA 551.86) failed the probe: OpenCL error" in why
    assert "OUT_OF_RESOURCES" in why


def test_an_amd_gpu_is_picked(monkeypatch):
    name, why = _choice(monkeypatch, {}, AMD)
    assert name == "gfx1030"
    assert why.startswith("gfx1030 (AMD Accelerated Parallel Processing 3614.0 (PAL,LC)) is a GPU")


def test_devices_prints_the_pick_and_its_reason(monkeypatch):
    _machine(monkeypatch, {}, INTEL_CPU, NVIDIA)
    monkeypatch.setattr(devices_command, "_device_lines", lambda c: [f"  {c.selector}  {c.device.name}"])
    monkeypatch.setattr(devices_command, "_environment_lines", lambda: [])
    report = devices_command.devices_report()
    assert "The toolkit would pick: NVIDIA GeForce RTX 3060 Laptop GPU (NVIDIA CUDA, " in report
    assert "  why: NVIDIA GeForce RTX 3060 Laptop GPU (NVIDIA CUDA 551.86) is a GPU and passed the probe" in report


def test_no_opencl_at_all_says_what_to_install_and_devices_exits_2(monkeypatch, capsys):
    _machine(monkeypatch, {})
    monkeypatch.setattr(device, "list_devices", lambda: [])
    with pytest.raises(device.NoOpenCLError, match="No OpenCL platform was found"):
        device.pick_device()
    from toolkit.cli import main
    assert main(["devices"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: No OpenCL platform was found. To get one on ") and "Traceback" not in err


@pytest.mark.parametrize("system, machine, says", [
    ("Darwin", "arm64", ["macOS", "Apple's", "pip install --force-reinstall --only-binary=:all: pyopencl"]),
    ("Windows", "AMD64", ["x86-64 Windows", "GPU vendor's OpenCL driver", "pip install intel-opencl-rt intel-cmplr-lib-rt"]),
    ("Windows", "ARM64", ["Windows on ARM", "GPU vendor's OpenCL driver", "OpenCL and OpenGL Compatibility Pack"]),
    ("Linux", "x86_64", ["x86-64 Linux", "pip install pocl-binary-distribution", "pocl-opencl-icd"]),
    ("Linux", "aarch64", ["ARM Linux", "sudo apt-get install pocl-opencl-icd", "conda-forge"]),
])
def test_what_to_install_is_named_per_system(system, machine, says):
    text = how_to_get_opencl(system, machine)
    for part in says:
        assert part in text, text


def test_fixes_leave_out_what_is_installed():
    assert not any("intel-opencl-rt" in line for line in fixes_when_nothing_builds(True, "Windows", "AMD64"))
    linux = fixes_when_nothing_builds(False, "Linux", "x86_64")
    assert not any("pip install pocl-binary-distribution" in line for line in linux)   # it is what failed
    assert any("pocl-opencl-icd" in line for line in linux)
    assert any("pocl-opencl-icd" in line for line in fixes_when_nothing_builds(False, "Linux", "aarch64"))
