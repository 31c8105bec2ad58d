"""A path tracer's film kept on the device (toolkit/opencl/device_film.py, cl/film_accumulate.cl)
against the host's film (toolkit/core/film.py): the same float32 pass sums added in float64 in
the same order give the same bits, from 1e-6 to 1e6; a sample never written still raises, at the
end; a device without float64 keeps the host's film. BDPT's whole-image passes (DevicePassFilm)
likewise."""
from types import SimpleNamespace

import numpy as np
import pyopencl as cl
import pytest

from toolkit.core.film import Film
from toolkit.core.layout import FILM_PIXEL
from toolkit.opencl.device_film import DeviceFilm, DevicePassFilm, film_path, has_fp64
from toolkit.opencl.device_scene import DeviceScene
from toolkit.techniques import get_technique

PATH_TRACERS = ["pt_naive", "pt_inplace_regen", "pt_compact_regen"]


def device_buffer(queue, array):
    return cl.Buffer(queue.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=array)


@pytest.fixture
def fp64_queue(queue):
    if not has_fp64(queue.device):
        pytest.skip("the device has no cl_khr_fp64: the host's film is the only path")
    return queue


def films_on_and_off_the_device(queue, scene, technique):
    """({on_device: the film}, {on_device: bytes read back}) of `technique` rendering 16x8 pixels in
    four passes of one sample per pixel, counters off, with its film on the device and on the host."""
    from toolkit.opencl.traffic import Traffic
    cls, options = get_technique(technique)
    device_scene = DeviceScene(queue, scene)
    films, read = {}, {}
    for on_device in (True, False):
        tech = cls(queue, device_scene, count_simd=False, pass_spp=1, **options)
        tech.film_on_device = on_device
        with Traffic() as traffic:
            films[on_device] = tech.render(16, 8, 4, seed=5)
        read[on_device] = traffic.figures()["read_bytes"]
    assert films[True].device is not None and films[False].device is None
    return films, read


def pass_sums(rng, pixels, missing=0):
    """A FilmPixel array as a pass's film_reduce would write it: float32 sums spanning 1e-6 .. 1e6."""
    sums = FILM_PIXEL.zeros(pixels)
    sums["sum"] = 10.0 ** rng.uniform(-6, 6, (pixels, 4))
    sums["sum_sq"] = 10.0 ** rng.uniform(-6, 6, (pixels, 4))
    sums["dropped"] = rng.integers(0, 3, pixels)
    sums["missing"][:missing] = 1
    return sums


def test_passes_added_on_the_device_give_the_host_film_bits_from_1e_minus_6_to_1e6(fp64_queue):
    """Twelve passes of sums spanning twelve decades: each float64 sum is the host's bit for bit
    (a float32 converts to float64 exactly and both add in IEEE order), so are the dropped samples."""
    pixels, rng = 97, np.random.default_rng(11)
    host, device = Film(pixels, 1), Film(pixels, 1)
    device.keep_on_device(DeviceFilm(fp64_queue, pixels))
    for _ in range(12):
        sums = pass_sums(rng, pixels)
        host.add_pixel_sums(sums["sum"][:, :3], sums["sum_sq"][:, :3], 4, int(sums["dropped"].sum()))
        device.device.add(device_buffer(fp64_queue, sums), 4)
        device.add_device_pass(4)
    assert device.sum.tobytes() == host.sum.tobytes() and device.sum_sq.tobytes() == host.sum_sq.tobytes()
    assert device.nonfinite_samples == host.nonfinite_samples > 0
    assert device.image().tobytes() == host.image().tobytes()
    # a value of 1e-6 beside a sum near 1e6 still counts: float64 keeps 1e-12 of its size
    assert np.all(device.sum > 0)


def test_a_sample_never_written_raises_when_the_film_is_read(fp64_queue):
    pixels, rng = 8, np.random.default_rng(3)
    film = Film(pixels, 1)
    film.keep_on_device(DeviceFilm(fp64_queue, pixels, owner="pt_test"))
    film.device.add(device_buffer(fp64_queue, pass_sums(rng, pixels)), 2)
    film.add_device_pass(2)
    film.device.add(device_buffer(fp64_queue, pass_sums(rng, pixels, missing=3)), 2)
    film.add_device_pass(2)
    for _ in range(2):   # and again: the film never shows sums with a sample missing
        with pytest.raises(RuntimeError, match=r"pt_test: 3 of 32 samples were never written"):
            film.image()


@pytest.mark.parametrize("technique", PATH_TRACERS)
def test_a_render_on_the_device_film_has_the_host_films_bits(fp64_queue, cornell_box, technique):
    """Four passes of one sample per pixel (so the film adds passes), counters off: the device's
    film and the host's give the same image, error and sums, bit for bit."""
    films, _ = films_on_and_off_the_device(fp64_queue, cornell_box, technique)
    for what in ("sum", "sum_sq", "count"):
        assert getattr(films[True], what).tobytes() == getattr(films[False], what).tobytes(), what
    assert films[True].stderr().tobytes() == films[False].stderr().tobytes()
    assert films[True].nonfinite_samples == films[False].nonfinite_samples


def test_bdpt_passes_added_on_the_device_give_the_host_film_bits_from_1e_minus_6_to_1e6(fp64_queue):
    """Nine whole-image passes (BDPT's: a pass's RGB sums, the records dropped in .w) of 1 to 9
    samples per pixel, their sums spanning twelve decades: the device divides, multiplies and adds
    in float64 as Film.add_pass does, so the passes' sums, the image and its error are the host's bits."""
    pixels, rng = 97, np.random.default_rng(13)
    host, device = Film(pixels, 1), Film(pixels, 1)
    device.keep_passes_on_device(DevicePassFilm(fp64_queue, pixels))
    for spp in range(1, 10):
        image = (10.0 ** rng.uniform(-6, 6, (pixels, 4))).astype(np.float32)
        image[:, 3] = rng.integers(0, 3, pixels)
        host.add_pass(image[:, :3].astype(np.float64) / spp, spp, nonfinite=int(image[:, 3].sum()))
        device.device.add(device_buffer(fp64_queue, image), spp)
        device.add_device_image_pass(spp)
    for what in ("pass_sum", "pass_sum_sq", "count"):
        assert getattr(device, what).tobytes() == getattr(host, what).tobytes(), what
    assert device.passes == host.passes == 9
    assert device.image().tobytes() == host.image().tobytes()
    assert device.stderr().tobytes() == host.stderr().tobytes()
    assert device.nonfinite_samples == host.nonfinite_samples > 0
    with pytest.raises(ValueError, match="kept on a device"):
        device.add_pass(np.ones((pixels, 3)), 1)


@pytest.mark.parametrize("technique", ["bdpt_naive_connect", "bdpt_parallel_connect"])
def test_a_bdpt_render_on_the_device_film_has_the_host_films_bits(fp64_queue, cornell_box, technique):
    """Four passes of one sample per pixel: the film on the device and the host's give the same
    image, error and sums, bit for bit, and the device's reads no pass's image back."""
    films, read = films_on_and_off_the_device(fp64_queue, cornell_box, technique)
    pass_image = 16 * 8 * 16                    # a pass's float4 image, read back by the host's film
    film_end = sum(getattr(films[True], what).nbytes for what in ("pass_sum", "pass_sum_sq", "count"))
    # on the device: the film's sums once, at the end, and the listings' few ints; on the host: every pass's image
    assert read[False] >= 4 * pass_image and read[True] - film_end < pass_image, (read, film_end)
    assert films[True].passes == films[False].passes == 4
    for what in ("pass_sum", "pass_sum_sq", "count"):
        assert getattr(films[True], what).tobytes() == getattr(films[False], what).tobytes(), what
    assert np.any(films[True].pass_sum > 0)
    assert films[True].stderr().tobytes() == films[False].stderr().tobytes()
    assert films[True].nonfinite_samples == films[False].nonfinite_samples


def test_a_render_with_an_unwritten_sample_raises_at_its_end(fp64_queue, cornell_box):
    """collect adds a pass whose sample (pixel 5, sample 1) was never written: the render's end raises."""
    cls, options = get_technique("pt_naive")
    tech = cls(fp64_queue, DeviceScene(fp64_queue, cornell_box), count_simd=False, **options)
    film, pixels = Film(4, 2), 8
    radiance = np.zeros((2 * pixels, 4), np.float32)
    radiance[pixels + 5, 3] = -1.0
    tech.collect(film, device_buffer(fp64_queue, radiance), 2 * pixels)
    with pytest.raises(RuntimeError, match=r"pt_naive: 1 of 16 samples were never written"):
        tech.end_render(film)


def test_a_film_keeps_its_sums_in_one_place():
    film = Film(2, 1)
    film.add_pixel_sums(np.ones((2, 3)), np.ones((2, 3)), 1)
    with pytest.raises(ValueError, match="before its first pass"):
        film.keep_on_device(object())
    fresh = Film(2, 1)
    fresh.keep_on_device(object())
    with pytest.raises(ValueError, match="kept on a device"):
        fresh.add_pixel_sums(np.ones((2, 3)), np.ones((2, 3)), 1)


def test_devices_says_where_a_path_tracers_film_adds():
    assert "kept on the device" in film_path(SimpleNamespace(extensions="cl_khr_fp64 cl_khr_byte_addressable_store"))
    assert "on the host, each pass's sums read back" in film_path(SimpleNamespace(extensions="cl_khr_fp16"))
