"""The warp width W of the SIMD counters defaults from the device (issue 14, item 7): 32 on
NVIDIA, 64 on AMD (or the wavefront width the driver reports), 16 on Intel GPUs (or their
smallest sub-group size where 16 is not one), 32 on a CPU, where the counters model a GPU."""
from types import SimpleNamespace

import pyopencl as cl
import pytest

import toolkit
from toolkit.opencl import device
from toolkit.measure.compare import format_table
from toolkit.opencl.device_model import choose_warp_width, device_warp_width
from toolkit.cli import devices_report


@pytest.mark.parametrize("description, expected", [
    (dict(is_gpu=True, vendor="NVIDIA Corporation", vendor_id=0x10DE), 32),
    (dict(is_gpu=True, vendor="NVIDIA Corporation"), 32),
    (dict(is_gpu=True, vendor="Advanced Micro Devices, Inc.", vendor_id=0x1002), 64),
    (dict(is_gpu=True, vendor="AMD", vendor_id=None), 64),
    (dict(is_gpu=True, vendor="Advanced Micro Devices, Inc.", vendor_id=0x1002, wavefront_width=32), 32),   # RDNA
    (dict(is_gpu=True, vendor="Advanced Micro Devices, Inc.", vendor_id=0x1002, wavefront_width=64), 64),
    (dict(is_gpu=True, vendor="Advanced Micro Devices, Inc.", wavefront_width=0), 64),     # nonsense: ignored
    (dict(is_gpu=True, vendor="Intel(R) Corporation", vendor_id=0x8086), 16),
    (dict(is_gpu=True, vendor="Intel(R) Corporation", vendor_id=0x8086, sub_group_sizes=[8, 16, 32]), 16),
    (dict(is_gpu=True, vendor="Intel(R) Corporation", vendor_id=0x8086, sub_group_sizes=[32, 64]), 32),
    (dict(is_gpu=True, vendor="Intel(R) Corporation", sub_group_sizes=[8]), 8),
    (dict(is_gpu=True, vendor="Apple", vendor_id=0x1027F00), 32),
    (dict(is_gpu=True, vendor="ARM"), 32),
    (dict(is_gpu=False, vendor="Intel(R) Corporation", vendor_id=0x8086), 32),                # Intel's CPU runtime
    (dict(is_gpu=False, vendor="AuthenticAMD", vendor_id=0x1002), 32),                        # PoCL on an AMD CPU
    (dict(is_gpu=False, vendor="NVIDIA Corporation", vendor_id=0x10DE), 32),
])
def test_the_default_warp_width_follows_the_vendor(description, expected):
    width, why = choose_warp_width(**description)
    assert width == expected
    assert why and isinstance(why, str)


def test_the_reasons_name_the_choice():
    assert "NVIDIA" in choose_warp_width(True, "NVIDIA Corporation")[1]
    assert "AMD" in choose_warp_width(True, "Advanced Micro Devices, Inc.")[1]
    assert "Intel" in choose_warp_width(True, "Intel(R) Corporation")[1]
    assert "CPU" in choose_warp_width(False, "Intel(R) Corporation")[1]


def _fake_device(kind, vendor, vendor_id, extensions="", **properties):
    return SimpleNamespace(type=kind, vendor=vendor, vendor_id=vendor_id, extensions=extensions,
                           platform=SimpleNamespace(name=f"{vendor} OpenCL"), **properties)


def test_device_properties_are_read_only_where_the_extension_is_there():
    gpu, cpu = cl.device_type.GPU, cl.device_type.CPU
    rdna = _fake_device(gpu, "Advanced Micro Devices, Inc.", 0x1002, "cl_khr_fp64 cl_amd_device_attribute_query",
                        wavefront_width_amd=32)
    assert device_warp_width(rdna)[0] == 32
    # Without the extension the property is not asked for (it would raise on a real device).
    gcn = _fake_device(gpu, "Advanced Micro Devices, Inc.", 0x1002, "cl_khr_fp64")
    assert device_warp_width(gcn)[0] == 64
    arc = _fake_device(gpu, "Intel(R) Corporation", 0x8086, "cl_intel_required_subgroup_size",
                       sub_group_sizes_intel=[8, 16, 32])
    assert device_warp_width(arc)[0] == 16
    assert device_warp_width(_fake_device(gpu, "NVIDIA Corporation", 0x10DE))[0] == 32
    assert device_warp_width(_fake_device(cpu, "GenuineIntel", 0x8086))[0] == 32
    oclgrind = _fake_device(gpu | cpu | cl.device_type.ACCELERATOR, "University of Bristol", 0)
    assert device_warp_width(oclgrind) == (32, choose_warp_width(False)[1])     # a simulator on the CPU
    # A driver that lists the extension but fails the query: the vendor's default.
    class Failing(SimpleNamespace):
        @property
        def wavefront_width_amd(self):
            raise cl.LogicError("clGetDeviceInfo failed: INVALID_VALUE")
    broken = Failing(type=gpu, vendor="Advanced Micro Devices, Inc.", vendor_id=0x1002,
                     extensions="cl_amd_device_attribute_query", platform=SimpleNamespace(name="AMD APP"))
    assert device_warp_width(broken)[0] == 64


def test_devices_render_and_compare_say_which_width_is_used(queue, cornell_box):
    expected, why = device_warp_width(queue.device)
    assert f"SIMD counters: warps of {expected}" in devices_report()
    result = toolkit.render(cornell_box, "pt_naive", spp=1, resolution=(8, 8), device=None)
    assert result.stats["warp_width"] == device_warp_width(device.get_queue().device)[0]
    assert result.stats["warp_width_source"] == device_warp_width(device.get_queue().device)[1]
    given = toolkit.render(cornell_box, "pt_naive", spp=1, resolution=(8, 8), warp_width=8)
    assert given.stats["warp_width"] == 8 and given.stats["warp_width_source"] == "given"
    row = {"seconds": 1.0, "samples_per_second": 1.0, "simd_efficiency": {"overall": 0.5},
           "traversal_efficiency": {}, "traversal_steps": 1.0, "bvh": "wide", "rmse": None, "rmse_vs": {}}
    text = format_table({"pt_naive": dict(row, warp_width=64, warp_width_source="AMD wavefront (GCN/CDNA)")})
    assert "warps of 64 " in text and "W = 64: AMD wavefront (GCN/CDNA)" in text
    given = format_table({"pt_naive": dict(row, warp_width=16, warp_width_source="given")})
    assert "warps of 16 " in given and "W = " not in given
