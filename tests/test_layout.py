"""Host and device agree on every generated layout, and kernels stay short enough to read."""
import numpy as np
import pyopencl as cl
import pytest

from toolkit.core import layout

from toolkit.opencl import program
from toolkit.techniques import TECHNIQUES


def test_every_generated_struct_has_numpys_sizeof_and_offsetof_on_the_device(queue):
    built = program.build(queue, "layout_check.cl")
    checks = layout.layout_checks()
    out = np.full(len(checks), -1, np.int32)
    buffer = cl.Buffer(queue.context, cl.mem_flags.WRITE_ONLY, out.nbytes)
    program.kernel(built, "layout_check")(queue, (1,), None, buffer)
    cl.enqueue_copy(queue, out, buffer)
    wrong = [f"{what}: device {got}, numpy {want}" for (what, _, want), got in zip(checks, out) if got != want]
    assert not wrong, wrong
    assert len(checks) > 2 * len(layout.RECORDS)


def test_float4_fields_are_16_byte_aligned_like_c():
    record = layout.Record("Probe", [("a", "int"), ("b", "float4")])
    assert record.dtype.fields["b"][1] == 16 and record.dtype.itemsize == 32


@pytest.mark.parametrize("name", sorted(TECHNIQUES))
def test_no_kernel_takes_more_than_16_arguments(queue, cornell_spheres, name):
    from toolkit.opencl.device_scene import DeviceScene
    tech = TECHNIQUES[name](queue, DeviceScene(queue, cornell_spheres))
    counts = {k.function_name: k.num_args for k in tech.kernels.program.all_kernels()}
    assert counts and max(counts.values()) <= 16, counts


def test_named_w_lanes_are_the_fourth_float_of_their_field_on_both_sides(queue, tmp_path):
    from toolkit.core.packed_w import packed_w_dtype
    (tmp_path / "lanes.cl").write_text('#include "common.h"\n__kernel void lanes(__global Subpath* out) {\n'
                                       '    Subpath p = {.origin = (float4)(0.0f), .beta = (float4)(0.0f)};\n'
                                       '    SUBPATH_PDF_DIR(&p) = 2.5f;\n    SUBPATH_RR_NORMALISER(&p) = 7.0f;\n'
                                       '    out[0] = p;\n}\n')
    built = program.build(queue, "lanes.cl", directory=tmp_path)
    out = np.zeros(1, packed_w_dtype(layout.SUBPATH, layout.SUBPATH_PACKED_W))
    assert out.dtype.itemsize == layout.SUBPATH.dtype.itemsize
    buffer = cl.Buffer(queue.context, cl.mem_flags.WRITE_ONLY, out.nbytes)
    program.kernel(built, "lanes")(queue, (1,), None, buffer)
    cl.enqueue_copy(queue, out, buffer)
    assert out["pdf_dir"][0] == out["origin"][0, 3] == 2.5
    assert out["rr_normaliser"][0] == out["beta"][0, 3] == 7.0


def test_a_float3_and_the_float_after_it_share_one_float4_of_the_stream():
    """ShadowRay's origin and length are two named fields, one 16-byte word in its stream."""
    ray = layout.SHADOW_RAY
    assert ray.soa_arrays[0] == ("origin", "float4", ["origin", "length"])
    assert [a for a, _, _ in ray.soa_arrays] == ["origin", "dir", "contribution", "slot"]
    assert sum(ray.dtype[a].itemsize for a, _ in ray.soa_fields) == 52   # 16 + 16 + 16 + 4, as before
    assert ray.soa_offset("slot", 8) == 3 * 16 * 8
    with pytest.raises(KeyError, match="the .w of the array 'origin'"):
        ray.soa_offset("length", 8)
    # a float3 alone (or before a non-float) keeps an array of its own
    alone = layout.Record("Probe", [("p", "float3"), ("n", "int")])
    assert alone.soa_arrays == [("p", "float3", ["p"]), ("n", "int", ["n"])]
    assert alone.dtype.fields["n"][1] == 16   # a float3 takes 16 bytes in OpenCL C


def test_a_shadow_ray_survives_its_stream_on_the_device(queue, tmp_path):
    """The generated store puts length in origin's .w, where the host's soa_offset finds it."""
    (tmp_path / "roundtrip.cl").write_text("""#include "common.h"
__kernel void roundtrip(__global void* stream, const int capacity, __global float* out) {
    ShadowRay r = {.origin = (float3)(1.0f, 2.0f, 3.0f), .length = 4.0f, .dir = (float4)(5.0f),
                   .contribution = (float4)(6.0f), .slot = 7};
    ShadowRaySoA s = shadow_ray_soa(stream, capacity);
    shadow_ray_store(s, 1, &r);
    ShadowRay back = shadow_ray_load(s, 1);
    out[0] = back.origin.x; out[1] = back.origin.y; out[2] = back.origin.z; out[3] = back.length;
    out[4] = back.dir.x; out[5] = back.contribution.x; out[6] = (float)back.slot;
}
""")
    built = program.build(queue, "roundtrip.cl", directory=tmp_path)
    capacity = 4
    stream = layout.SHADOW_RAY.soa_buffer(queue.context, capacity)
    out = cl.Buffer(queue.context, cl.mem_flags.WRITE_ONLY, 7 * 4)
    program.launch(queue, program.kernel(built, "roundtrip"), 1, stream, np.int32(capacity), out)
    back, word = np.empty(7, np.float32), np.empty(4, np.float32)
    cl.enqueue_copy(queue, back, out)
    cl.enqueue_copy(queue, word, stream, src_offset=layout.SHADOW_RAY.soa_offset("origin", capacity) + 16)
    assert back.tolist() == [1, 2, 3, 4, 5, 6, 7] and word.tolist() == [1, 2, 3, 4]


def test_a_record_is_made_with_every_field_named():
    made = layout.PT_PASS.record(seed=3, sample_base=8, budget=100, capacity=64)
    assert (int(made["seed"]), int(made["budget"])) == (3, 100) and made.dtype == layout.PT_PASS.dtype
    with pytest.raises(TypeError, match="missing fields \\['capacity'\\]"):
        layout.PT_PASS.record(seed=3, sample_base=8, budget=100)
    with pytest.raises(TypeError, match="unknown fields \\['spp'\\]"):
        layout.PT_PASS.record(seed=3, sample_base=8, budget=100, capacity=64, spp=2)


def test_a_hit_record_survives_its_stream_on_the_device(queue, tmp_path):
    """HitRecord (trace -> shade in pt_compact_regen): two arrays, t then tri, where soa_offset says."""
    hit = layout.HIT_RECORD
    assert [a for a, _, _ in hit.soa_arrays] == ["t", "tri"] and hit.dtype.itemsize == 8
    (tmp_path / "hit.cl").write_text("""#include "common.h"
__kernel void hit_roundtrip(__global void* stream, const int capacity, __global float* out) {
    HitRecord h = {.t = 2.5f, .tri = 9};
    HitRecordSoA s = hit_record_soa(stream, capacity);
    hit_record_store(s, 3, &h);
    HitRecord back = hit_record_load(s, 3);
    out[0] = back.t; out[1] = (float)back.tri;
}
""")
    built = program.build(queue, "hit.cl", directory=tmp_path)
    capacity = 4
    stream = hit.soa_buffer(queue.context, capacity)
    out = cl.Buffer(queue.context, cl.mem_flags.WRITE_ONLY, 2 * 4)
    program.launch(queue, program.kernel(built, "hit_roundtrip"), 1, stream, np.int32(capacity), out)
    back, tri = np.empty(2, np.float32), np.empty(1, np.int32)
    cl.enqueue_copy(queue, back, out)
    cl.enqueue_copy(queue, tri, stream, src_offset=hit.soa_offset("tri", capacity) + 3 * 4)
    assert back.tolist() == [2.5, 9.0] and tri.tolist() == [9]
