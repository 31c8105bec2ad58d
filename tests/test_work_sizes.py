"""Stream and pool sizes follow the device (issue 14, item 2 and check 4): compute units x
resident work-items per unit on a GPU, the project's sizes on a CPU, shrunk to the device's
memory; a size given by hand is refused with a clear error where the device cannot hold its
buffers or its indices would overflow the kernels' 32-bit ints. The devices here are fake
descriptions (like tests/test_warp_width.py), and the 64-bit index path of the vertex memory is
checked with a tiny kernel instead of gigabytes of memory."""
from types import SimpleNamespace

import numpy as np
import pyopencl as cl
import pytest

import toolkit
from toolkit.opencl import device
from toolkit.opencl import program
from toolkit.core.layout import BDPT_VERTEX
from toolkit.core.validate import InputError
from toolkit.opencl.work_sizes import (CPU_CHAINS_PER_UNIT, CPU_POOL_SIZE, CPU_STREAM_SIZE, INT_MAX, buffer_plan, check_fits,
                                choose_work_sizes, device_work_sizes, problems)
from toolkit.cli import devices_report

GiB = 2**30
H200 = dict(is_gpu=True, vendor="NVIDIA Corporation", vendor_id=0x10DE, name="NVIDIA H200", compute_units=132,
            compute_capability=(9, 0), max_alloc=35 * GiB, global_memory=140 * GiB)


@pytest.mark.parametrize("description, expected", [
    # 132 SMs x 2048 resident threads (compute capability 9.0).
    (H200, 132 * 2048),
    # Turing keeps 1024 threads per SM, Ada 1536; without the capability query: 2048.
    (dict(H200, name="RTX 2080", compute_units=46, compute_capability=(7, 5)), 46 * 1024),
    (dict(H200, name="RTX 4090", compute_units=128, compute_capability=(8, 9)), 128 * 1536),
    (dict(H200, compute_capability=None), 132 * 2048),
    # AMD GCN/CDNA: 4 SIMDs x 10 wavefronts x 64; the driver's SIMD count and wavefront width where it reports them.
    (dict(is_gpu=True, vendor="Advanced Micro Devices, Inc.", vendor_id=0x1002, compute_units=110,
          max_alloc=50 * GiB, global_memory=64 * GiB), 110 * 2560),
    (dict(is_gpu=True, vendor="Advanced Micro Devices, Inc.", vendor_id=0x1002, compute_units=40, simd_per_unit=4,
          wavefront_width=32, max_alloc=12 * GiB, global_memory=16 * GiB), 40 * 4 * 10 * 32),
    # Intel: EUs x threads per EU x SIMD width (7 threads before Xe-HPG, 8 on Arc); 24 x 112 rounded up to 256.
    (dict(is_gpu=True, vendor="Intel(R) Corporation", vendor_id=0x8086, name="Intel(R) UHD Graphics 630",
          compute_units=24, warp_width=16, max_alloc=4 * GiB, global_memory=12 * GiB), 2816),
    (dict(is_gpu=True, vendor="Intel(R) Corporation", vendor_id=0x8086, name="Intel(R) Arc(TM) A770 Graphics",
          compute_units=512, warp_width=16, max_alloc=4 * GiB, global_memory=16 * GiB), 512 * 8 * 16),
    (dict(is_gpu=True, vendor="Apple", compute_units=10, max_alloc=8 * GiB, global_memory=16 * GiB), 10 * 2048),
])
def test_a_gpu_gets_its_resident_work_items(description, expected):
    sizes = choose_work_sizes(**description)
    assert sizes.stream_size == sizes.pool_size == expected
    assert expected % 256 == 0 and "compute units" in sizes.why
    # What was chosen fits: buffers the device can allocate, indices below 2^31.
    assert problems(buffer_plan(stream_size=sizes.stream_size, pool_size=sizes.pool_size),
                    description["max_alloc"], description["global_memory"]) == []


def test_a_cpu_keeps_the_project_sizes():
    for vendor in ("AuthenticAMD", "GenuineIntel", "NVIDIA Corporation"):
        sizes = choose_work_sizes(False, compute_units=64, vendor=vendor, max_alloc=4 * GiB, global_memory=16 * GiB)
        assert (sizes.stream_size, sizes.pool_size) == (CPU_STREAM_SIZE, CPU_POOL_SIZE) == (1 << 15, 1 << 12)
        assert "CPU" in sizes.why


def test_a_small_device_gets_smaller_sizes():
    """A GPU whose memory cannot hold a pool of its resident samples (64 vertices of 96 bytes
    each, two subpaths) gets a pool halved until it fits, and says so."""
    small = dict(H200, max_alloc=256 * 2**20, global_memory=1 * GiB)
    sizes = choose_work_sizes(**small)
    assert sizes.pool_size < 132 * 2048 and "halved" in sizes.why
    assert problems(buffer_plan(pool_size=sizes.pool_size), small["max_alloc"], small["global_memory"]) == []
    assert problems(buffer_plan(pool_size=2 * sizes.pool_size), small["max_alloc"], small["global_memory"])


def _fake_device(max_alloc, global_memory):
    return SimpleNamespace(max_mem_alloc_size=max_alloc, global_mem_size=global_memory)


def test_a_size_the_device_cannot_hold_is_refused_with_the_reason():
    small = _fake_device(64 * 2**20, 1 * GiB)
    with pytest.raises(InputError, match=r"stream_size 4,194,304 does not fit.*CL_DEVICE_MAX_MEM_ALLOC_SIZE"):
        check_fits(small, "stream_size", 1 << 22)
    # 2^22 samples x 4159 strategies each would overflow the int scan of parallel connect.
    with pytest.raises(InputError, match=r"pool_size .* index .* 2\^31 - 1"):
        check_fits(_fake_device(1 << 50, 1 << 52), "pool_size", 1 << 22)
    with pytest.raises(InputError, match="stream_size 0 is outside"):
        check_fits(small, "stream_size", 0)
    assert check_fits(small, "pool_size", 1000) == 1000


def test_the_largest_indices_of_the_chosen_sizes_fit_an_int():
    """The int indices the kernels form (buffer_plan's third column) at the largest pool that
    32-bit strategy counts allow, and beyond it."""
    largest = INT_MAX // ((65 * 64) - 1)
    assert all(index <= INT_MAX for _, _, index in buffer_plan(pool_size=largest))
    assert any(index > INT_MAX for _, _, index in buffer_plan(pool_size=largest + 1))


def test_vertex_word_offsets_are_formed_in_64_bits(queue):
    """vertex_word(index, w) (cl/vertex_memory.h) at vertex indices whose word offsets pass
    2^31 and 2^32 (pools of 1.4M samples and more), computed by the device."""
    built = program.build(queue, "index_test.cl", {"MAX_VERTICES": 64})
    index = np.array([0, 1, 2**31 // 24 - 1, 2**31 // 24 + 1, 200_000_000, INT_MAX], np.int32)
    word = np.array([0, 23, 23, 0, 7, 23], np.int32)
    mf = cl.mem_flags
    buffers = [cl.Buffer(queue.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=a) for a in (index, word)]
    out = cl.Buffer(queue.context, mf.WRITE_ONLY, 8 * len(index))
    program.launch(queue, program.kernel(built, "vertex_word_test"), len(index), np.int32(len(index)), *buffers, out)
    result = np.empty(2 * len(index), np.uint32)
    cl.enqueue_copy(queue, result, out)
    words_per_vertex = BDPT_VERTEX.dtype.itemsize // 4
    expected = index.astype(np.int64) * words_per_vertex + word
    assert expected.max() > 2**32
    np.testing.assert_array_equal(result.view(np.uint64), expected)


@pytest.mark.parametrize("technique, option, size", [("pt_inplace_regen", "stream_size", 300),
                                                      ("pt_compact_regen", "stream_size", 300),
                                                      ("bdpt_parallel_connect", "pool_size", 100)])
def test_a_given_size_is_used_and_does_not_change_the_image(cornell_box, technique, option, size):
    """Random numbers are keyed by sample, so a stream or pool of another size computes the same
    samples: the images agree to float rounding (rtol as in tests/test_strategies.py)."""
    default = toolkit.render(cornell_box, technique=technique, spp=2, seed=7, resolution=(24, 16))
    given = toolkit.render(cornell_box, technique=technique, spp=2, seed=7, resolution=(24, 16), options={option: size})
    assert default.stats[option] == getattr(device_work_sizes(device.get_queue().device), option)
    assert given.stats[option] == size and given.stats["work_sizes_source"] == "given"
    np.testing.assert_allclose(given.image, default.image, rtol=1e-5, atol=1e-6)
    with pytest.raises(InputError, match=f"{option} 0 is outside"):
        toolkit.render(cornell_box, technique=technique, spp=1, resolution=(4, 4), options={option: 0})


def test_devices_shows_the_sizes(queue):
    sizes = device_work_sizes(queue.device)
    assert f"in flight: {sizes.text()}" in devices_report()


def test_mlt_chains_fill_the_device_and_no_more():
    """mlt's chains (issue 40): every chain more adds startup bias, so a CPU gets as many per core
    as hide an iteration's fixed launch costs (CPU_CHAINS_PER_UNIT), not its whole BDPT pool; a GPU one per
    resident work-item, within the chains' limit of 2^18 (an H200 has 270,336)."""
    cpu = choose_work_sizes(False, compute_units=2, max_alloc=4 * GiB, global_memory=16 * GiB)
    assert cpu.chains == 2 * CPU_CHAINS_PER_UNIT < cpu.pool_size
    many_cores = choose_work_sizes(False, compute_units=64, max_alloc=4 * GiB, global_memory=16 * GiB)
    assert many_cores.chains == many_cores.pool_size            # never more chains than slots
    assert choose_work_sizes(**H200).chains == 1 << 18
    small_gpu = dict(H200, name="RTX 2080", compute_units=46, compute_capability=(7, 5))
    assert choose_work_sizes(**small_gpu).chains == 46 * 1024
