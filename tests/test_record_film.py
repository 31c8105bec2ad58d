"""Connection records summed per pixel on the device (cl/record_film.cl, toolkit/opencl/record_film.py),
against exact sums on the host: each record rounded to a multiple of 2^-48, the sum of a pixel's
records in Python integers, rounded once to float32. The device must give exactly those bits,
with 64-bit atomics and with 32-bit ones, in any order of the records; a record that is not
finite or beyond FILM_RECORD_LIMIT is counted at its pixel, never added."""
from fractions import Fraction
from types import SimpleNamespace

import numpy as np
import pyopencl as cl
import pytest

from toolkit.core.layout import FILM_FRACTION_BITS, FILM_RECORD_LIMIT
from toolkit.opencl.record_film import RecordFilm, film_path, film_word_bits, unit_exponent_for

EPS = 2.0 ** -24     # float32's unit roundoff
WORDS = (32, 64)


def device_sums(queue, values, pixels, npix, word_bits, weighted=False, batches=1, unit_exponent=0):
    """(RGB sums (npix, 3), dropped (npix,)) of records `values` (n, 4) float32 at `pixels` (n,) int32,
    added in `batches` launches (as a pass's connect phases add theirs)."""
    film = RecordFilm(queue, npix, word_bits=word_bits, unit_exponent=unit_exponent)
    buffers = []
    for part in np.array_split(np.arange(len(values)), batches):
        v = cl.Buffer(queue.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                      hostbuf=np.ascontiguousarray(values[part]))
        p = cl.Buffer(queue.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                      hostbuf=np.ascontiguousarray(pixels[part]))
        buffers.append((v, p))
        film.add(v, p, len(part), weighted)
    result, done = film.resolve()
    done.wait()
    return result[:, :3], result[:, 3]


def rounded_to_float32(units):
    """The integer `units` (of 2^-48) as the nearest float32 (ties to even), exactly."""
    value = Fraction(units, 2 ** FILM_FRACTION_BITS)
    if value == 0:
        return np.float32(0.0)
    sign, value = (-1 if value < 0 else 1), abs(value)
    exponent = value.numerator.bit_length() - value.denominator.bit_length()
    if Fraction(2) ** exponent > value:
        exponent -= 1                               # now 2^exponent <= value < 2^(exponent + 1)
    step = Fraction(2) ** (exponent - 23)           # float32's spacing there
    q, r = divmod(value, step)
    if r > step / 2 or (r == step / 2 and q % 2 == 1):
        q += 1
    return np.float32(sign * float(q * step))


def exact_sums(values, pixels, npix):
    """Each record rounded to 2^-48 (ties to even, as rint), summed per pixel in Python integers,
    then rounded once to float32: what the device must give bit for bit."""
    totals = [[0, 0, 0] for _ in range(npix)]
    scaled = np.rint(values[:, :3].astype(np.float64) * 2.0 ** FILM_FRACTION_BITS)   # exact in float64
    for row, p in zip(scaled, pixels):
        for c in range(3):
            totals[p][c] += int(row[c])
    return np.array([[rounded_to_float32(t) for t in pixel] for pixel in totals], np.float32)


def extremes(n, npix, seed):
    """n records spanning 1e-6 .. 1e6 in every channel, at random pixels."""
    rng = np.random.default_rng(seed)
    values = np.zeros((n, 4), np.float32)
    values[:, :3] = 10.0 ** rng.uniform(-6, 6, (n, 3))
    return values, rng.integers(0, npix, n).astype(np.int32)


@pytest.mark.parametrize("word_bits", WORDS)
def test_records_from_1e_minus_6_to_1e6_sum_exactly_then_round_once(queue, word_bits):
    """20,000 records over 13 pixels (about 1,500 a pixel, in 3 launches): each pixel's sums are
    the exact sums of the records rounded to 2^-48, rounded once to float32 (bit for bit), so
    within half an ulp (EPS relative) of the float64 sums of the records themselves: a record of
    1e-6 loses nothing (its last bit is 2^-43), and a pixel of small records beside one of
    large records keeps its own precision."""
    npix = 13
    values, pixels = extremes(20000, npix, 11)
    got, dropped = device_sums(queue, values, pixels, npix, word_bits, batches=3)
    assert np.array_equal(got.view(np.uint32), exact_sums(values, pixels, npix).view(np.uint32))
    want = np.zeros((npix, 3))
    np.add.at(want, pixels, values[:, :3].astype(np.float64))
    assert np.all(np.abs(got - want) <= EPS * want)
    assert not dropped.any()


@pytest.mark.parametrize("word_bits", WORDS)
def test_records_below_the_fixed_points_last_bit_round_to_nearest_even(queue, word_bits):
    """Records from 1e-18 to 1e-6 (below 2^-25 a float has bits beyond 2^-48, which are rounded
    off), and exact ties: half a unit (2^-49) rounds to 0, one and a half to 2, 1.25 units to 1."""
    rng = np.random.default_rng(14)
    values = np.zeros((3000, 4), np.float32)
    values[:, :3] = 10.0 ** rng.uniform(-18, -6, (3000, 3))
    values[:3, :3] = np.float32([[2.0 ** -49, 3 * 2.0 ** -49, 5 * 2.0 ** -50]]) * np.float32([[1], [-1], [1]])
    pixels = rng.integers(0, 4, 3000).astype(np.int32)
    pixels[:3] = [3, 3, 2]
    got, _ = device_sums(queue, values, pixels, 4, word_bits)
    assert np.array_equal(got.view(np.uint32), exact_sums(values, pixels, 4).view(np.uint32))
    ties, _ = device_sums(queue, values[:1], np.int32([0]), 1, word_bits)
    assert ties[0].tolist() == [0.0, 2.0 ** -47, 2.0 ** -48]


@pytest.mark.parametrize("word_bits", WORDS)
def test_a_pixel_of_only_1e_minus_6_and_one_of_only_1e6(queue, word_bits):
    """The extremes alone, 4,096 records each: 4096 * 1e-6 and 4096 * 1e6 within half an ulp."""
    values = np.zeros((8192, 4), np.float32)
    values[:4096, :3], values[4096:, :3] = np.float32(1e-6), np.float32(1e6)
    pixels = np.repeat(np.int32([0, 1]), 4096)
    got, _ = device_sums(queue, values, pixels, 2, word_bits)
    for p, v in ((0, np.float32(1e-6)), (1, np.float32(1e6))):
        want = 4096 * float(v)
        assert np.all(np.abs(got[p] - want) <= EPS * want), (got[p], want)


def test_the_same_bits_with_either_word_size_and_in_any_order(queue):
    """Integer sums: 64-bit and 32-bit atomics, the records shuffled, split into other launches:
    the same bits. Signed records too (words in two's complement, carries through all four)."""
    npix = 7
    values, pixels = extremes(6000, npix, 3)
    values[::3, :3] *= -1.0                        # a third negative: the sums cross zero, borrow and carry
    first = device_sums(queue, values, pixels, npix, 64)[0]
    order = np.random.default_rng(4).permutation(len(values))
    for word_bits, batches in ((32, 1), (64, 5), (32, 4)):
        got = device_sums(queue, values[order], pixels[order], npix, word_bits, batches=batches)[0]
        assert np.array_equal(got.view(np.uint32), first.view(np.uint32))
    assert np.array_equal(first.view(np.uint32), exact_sums(values, pixels, npix).view(np.uint32))


@pytest.mark.parametrize("word_bits", WORDS)
def test_runs_of_records_on_one_pixel_sum_exactly(queue, word_bits):
    """A sample's records are consecutive and mostly on its pixel: a work-item sums such a run in
    registers before its atomics (FILM_RECORDS_PER_ITEM). Runs of every length, signed values
    (carries and borrows inside the registers' sums), against the exact sums."""
    npix = 9
    values, _ = extremes(4000, npix, 12)
    values[1::4, :3] *= -1.0
    pixels = np.sort(np.random.default_rng(13).integers(0, npix, 4000)).astype(np.int32)
    pixels[::37] = (pixels[::37] + 1) % npix              # runs broken here and there
    got, _ = device_sums(queue, values, pixels, npix, word_bits, batches=3)
    assert np.array_equal(got.view(np.uint32), exact_sums(values, pixels, npix).view(np.uint32))


@pytest.mark.parametrize("word_bits", WORDS)
def test_opposite_records_cancel_to_exactly_zero(queue, word_bits):
    values, pixels = extremes(3000, 3, 8)
    both = np.concatenate([values, -values])
    both[:, 3] = 0.0
    got, _ = device_sums(queue, both, np.concatenate([pixels, pixels]), 3, word_bits)
    assert np.array_equal(got, np.zeros((3, 3), np.float32))


@pytest.mark.parametrize("word_bits", WORDS)
def test_unwritten_non_finite_and_too_large_records_are_counted_not_added(queue, word_bits):
    rng = np.random.default_rng(9)
    values = rng.random((40, 4), dtype=np.float32)
    pixels = np.arange(40, dtype=np.int32) % 4
    pixels[5] = -1                                  # left unwritten by its connect phase
    values[6, 1] = np.nan                           # pixel 2
    values[7, 0] = np.inf                           # pixel 3
    values[9, 2] = np.float32(FILM_RECORD_LIMIT) * 2   # pixel 1: beyond what the film holds (unit 1)
    values[13, 2] = np.float32(FILM_RECORD_LIMIT)      # pixel 1: the largest it holds, kept
    got, dropped = device_sums(queue, values, pixels, 4, word_bits)
    assert dropped.tolist() == [0, 1, 1, 1]
    kept = np.ones(40, bool)
    kept[[5, 6, 7, 9]] = False
    want = np.zeros((4, 3))
    np.add.at(want, pixels[kept], values[kept, :3].astype(np.float64))
    assert np.all(np.abs(got - want) <= EPS * want) and np.isfinite(got).all()


@pytest.mark.parametrize("word_bits", WORDS)
def test_weighted_records_multiply_by_their_weight_in_float32(queue, word_bits):
    """The STRATEGY_IMAGES kernels' records (unweighted RGB, MIS weight): RGB * w in float32, as
    the normal kernels write it."""
    rng = np.random.default_rng(2)
    values = rng.random((500, 4), dtype=np.float32)
    pixels = rng.integers(0, 5, 500).astype(np.int32)
    got, _ = device_sums(queue, values, pixels, 5, word_bits, weighted=True)
    product = values.copy()
    product[:, :3] *= values[:, 3:]
    assert np.array_equal(got.view(np.uint32), exact_sums(product, pixels, 5).view(np.uint32))


@pytest.mark.parametrize("exponent", [-20, 20])
def test_records_in_units_of_a_power_of_two_give_the_same_bits_scaled(queue, exponent):
    """A scene 2^20 times darker or brighter (its film's unit_exponent_for follows its brightest
    light): its records, all scaled by 2^exponent, sum to the same bits scaled by 2^exponent."""
    values, pixels = extremes(3000, 5, 6)
    unit = device_sums(queue, values, pixels, 5, 64)[0]
    scaled = device_sums(queue, values * np.float32(2.0 ** exponent), pixels, 5, 64,
                         unit_exponent=unit_exponent_for(2.0 ** exponent))[0]
    assert np.array_equal(scaled, unit * np.float32(2.0 ** exponent))
    assert unit_exponent_for(2.0 ** exponent) == exponent + 1 and unit_exponent_for(17.0) == 5


def test_resolve_starts_the_next_pass_at_zero(queue):
    film = RecordFilm(queue, 3)
    v = cl.Buffer(queue.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                  hostbuf=np.ones((2, 4), np.float32))
    p = cl.Buffer(queue.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=np.int32([0, 2]))
    film.add(v, p, 2)
    first, done = film.resolve()
    second, done_too = film.resolve()
    done.wait(), done_too.wait()
    assert first[:, 0].tolist() == [1.0, 0.0, 1.0] and not second.any()


def test_the_device_says_which_way_it_adds(queue):
    """64-bit words where the device has cl_khr_int64_base_atomics, else 32-bit ones; `devices` says which."""
    assert film_word_bits(queue.device) in WORDS
    assert ("64-bit atomics" in film_path(queue.device)) == (film_word_bits(queue.device) == 64)
    without = SimpleNamespace(extensions="cl_khr_global_int32_base_atomics cl_khr_int64_extended_atomics")
    with_them = SimpleNamespace(extensions="cl_khr_fp64 cl_khr_int64_base_atomics")
    assert film_word_bits(without) == 32 and "32-bit atomics, carried" in film_path(without)
    assert film_word_bits(with_them) == 64 and "with 64-bit atomics" in film_path(with_them)
