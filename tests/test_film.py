"""The film's per-pass sums (toolkit/core/film.py, add_pixel_major): the fast path for a pass of
finite samples gives the same sums, bit for bit, as the general one, and a flagged or
non-finite sample is counted and left out, never added."""
import numpy as np

from toolkit.core.film import Film

PIXELS, SAMPLES = 12, 4


def a_pass(seed):
    rng = np.random.default_rng(seed)
    radiance = rng.random((SAMPLES * PIXELS, 4), dtype=np.float32) * 7
    radiance[:, 3] = 0.0     # .w = 0: written and finite
    return radiance


def test_finite_passes_sum_as_the_general_path_does():
    fast, general = Film(PIXELS, 1), Film(PIXELS, 1)
    for seed in range(3):
        radiance = a_pass(seed)
        fast.add_pixel_major(radiance)
        general._add_pixel_major_dropping(radiance.reshape(-1, PIXELS, 4))
    assert np.array_equal(fast.sum, general.sum) and np.array_equal(fast.sum_sq, general.sum_sq)
    assert np.array_equal(fast.count, general.count) and fast.nonfinite_samples == 0
    assert np.array_equal(fast.image(), general.image()) and np.array_equal(fast.stderr(), general.stderr())


def test_flagged_and_non_finite_samples_are_counted_and_left_out():
    radiance = a_pass(7)
    radiance[3, 3] = 1.0          # sample 0 of pixel 3: flagged by the kernel (path_finish)
    radiance[PIXELS + 5, 1] = np.nan   # sample 1 of pixel 5: NaN in green
    film = Film(PIXELS, 1)
    film.add_pixel_major(radiance)
    assert film.nonfinite_samples == 2
    kept = radiance.reshape(SAMPLES, PIXELS, 4)[..., :3].astype(np.float64)
    kept[0, 3] = 0.0
    kept[1, 5] = 0.0
    assert np.array_equal(film.sum, kept.sum(0)) and np.isfinite(film.sum).all()
