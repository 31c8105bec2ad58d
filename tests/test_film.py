"""A pass's samples summed per pixel on the device (cl/film_reduce.cl, toolkit/opencl/film_reduce.py),
against float64 sums on the host: the compensated float32 sum stays within a few roundings of
the pixel's sum however many samples it adds; a flagged, non-finite or unwritten sample is
counted and left out, never added; the firefly clamp scales a sample by its largest component."""
import numpy as np
import pytest

from toolkit.core.film import Film
from toolkit.opencl.film_reduce import FilmReduction
import pyopencl as cl

EPS = 2.0 ** -24     # float32's unit roundoff


def reduced(queue, radiance, pixels, clamp=None):
    """The device's FilmPixel sums of `radiance` (float32 (samples * pixels, 4), pixel-major)."""
    buffer = cl.Buffer(queue.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=radiance)
    result, done = FilmReduction(queue).reduce(buffer, pixels, len(radiance) // pixels, clamp)
    done.wait()
    return result


def host_sums(radiance, pixels):
    value = radiance.reshape(-1, pixels, 4)[..., :3].astype(np.float64)
    return value.sum(0), (value ** 2).sum(0)


def test_many_samples_of_every_magnitude_sum_to_within_a_few_roundings(queue):
    """4096 samples per pixel spanning 1e-6 .. 1e6 (a float32 running sum would lose the small
    ones): each pixel's sums within 4 roundings of the float64 sums. Kahan's bound is 2 eps |sum|
    plus O(n eps^2) sum |x|, here far below one rounding, so 4 eps leaves room for the float32
    rounding of each sample's square and nothing more."""
    pixels, samples = 37, 4096
    rng = np.random.default_rng(5)
    radiance = np.zeros((samples * pixels, 4), np.float32)
    radiance[:, :3] = 10.0 ** rng.uniform(-6, 6, (samples * pixels, 3))
    got = reduced(queue, radiance, pixels)
    want, want_sq = host_sums(radiance, pixels)
    assert np.all(np.abs(got["sum"][:, :3] - want) <= 4 * EPS * want)
    assert np.all(np.abs(got["sum_sq"][:, :3] - want_sq) <= 4 * EPS * want_sq)
    assert not got["missing"].any() and not got["dropped"].any()


def test_flagged_non_finite_and_unwritten_samples_are_counted_not_added(queue):
    pixels, samples = 12, 4
    radiance = np.random.default_rng(7).random((samples * pixels, 4), dtype=np.float32) * 7
    radiance[:, 3] = 0.0
    radiance[3, 3] = 1.0                  # sample 0 of pixel 3: flagged non-finite by the kernel (path_finish)
    radiance[pixels + 5, 1] = np.nan      # sample 1 of pixel 5: NaN in green
    radiance[2 * pixels + 6, 0] = 1e20    # sample 2 of pixel 6: its square is no float32
    radiance[3 * pixels + 8, 3] = -1.0    # sample 3 of pixel 8: never written
    got = reduced(queue, radiance, pixels)
    assert got["dropped"].tolist() == [0, 0, 0, 1, 0, 1, 1, 0, 0, 0, 0, 0]
    assert got["missing"].tolist() == [0] * 8 + [1] + [0] * 3
    kept = radiance.copy()
    kept[[3, pixels + 5, 2 * pixels + 6, 3 * pixels + 8], :3] = 0.0
    want, _ = host_sums(kept, pixels)
    assert np.allclose(got["sum"][:, :3], want, rtol=4 * EPS, atol=0) and np.isfinite(got["sum"]).all()


def test_clamp_scales_a_sample_by_its_largest_component(queue):
    radiance = np.array([[4.0, 2.0, 1.0, 0.0], [0.5, 0.2, 0.1, 0.0]], np.float32)   # two pixels, one sample
    got = reduced(queue, radiance, 2, clamp=2.0)
    assert got["sum"][0, :3].tolist() == [2.0, 1.0, 0.5]          # scaled by 2 / 4: same hue
    assert got["sum"][1, :3].tolist() == radiance[1, :3].tolist()  # under the clamp: untouched
    assert reduced(queue, radiance, 2)["sum"][0, :3].tolist() == [4.0, 2.0, 1.0]   # no clamp


def test_film_adds_pass_sums_in_float64():
    film = Film(3, 1)
    for _ in range(2):
        film.add_pixel_sums(np.ones((3, 3)), np.ones((3, 3)) * 2, samples=4, dropped=1)
    assert film.count.tolist() == [8, 8, 8] and film.nonfinite_samples == 2
    assert np.array_equal(film.image(), np.full((1, 3, 3), 0.25))
