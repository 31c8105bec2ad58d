"""Device choice: automatic pick, overrides, and a clear message when OpenCL is missing."""
import pyopencl as cl
import pytest

from toolkit import device


def test_no_platform_gives_instructions(monkeypatch):
    def no_platforms():
        raise cl.LogicError("clGetPlatformIDs failed: PLATFORM_NOT_FOUND_KHR")
    monkeypatch.setattr(cl, "get_platforms", no_platforms)
    assert device.list_devices() == []
    with pytest.raises(device.NoOpenCLError, match="pocl-binary-distribution"):
        device.pick_device()
    assert "pip install pocl-binary-distribution" in device.report()


def test_selectors_pick_the_named_device():
    found = device.list_devices()
    assert found, "the test environment needs an OpenCL device (PoCL)"
    pi, di, platform, dev = found[0]
    assert device.pick_device(f"{pi}:{di}")[1].int_ptr == dev.int_ptr
    assert device.pick_device(dev.name.split()[0])[1].int_ptr == dev.int_ptr
    with pytest.raises(device.NoOpenCLError, match="no OpenCL device"):
        device.pick_device("99:0")
    with pytest.raises(device.NoOpenCLError, match="no OpenCL device matches"):
        device.pick_device("no-such-device-name")


def test_environment_variable_overrides(monkeypatch):
    pi, di, _, dev = device.list_devices()[0]
    monkeypatch.setenv("PYOPENCL_CTX", f"{pi}:{di}")
    assert device.pick_device()[1].int_ptr == dev.int_ptr
    monkeypatch.setenv("PYOPENCL_CTX", "99:0")
    with pytest.raises(device.NoOpenCLError):
        device.pick_device()
