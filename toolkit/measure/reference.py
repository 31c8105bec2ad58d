"""Comparing a render with a reference image within statistical error.

The reference (256x256 Mitsuba render with its per-pixel standard error) is averaged over
k x k blocks to match a reduced-resolution render of the same camera: a 64x64 pixel covers
exactly a 4x4 block of reference pixels, and the box filter makes its expected value the block
mean. The z-test combines both standard errors and corrects for the number of pixels tested
(the two-sided tails and the correction are in `toolkit/core/stats.py`).
"""
from dataclasses import dataclass

import numpy as np

from toolkit.core.stats import bonferroni, normal_two_sided_p, rmse, student_t_two_sided_p  # noqa: F401 (rmse: here with the other errors)


def downsample(image, width, height):
    """Average an (H, W, C) image over blocks so it becomes (height, width, C)."""
    h, w, c = image.shape
    if h % height or w % width:
        raise ValueError(f"cannot average a {w}x{h} image down to {width}x{height}")
    return image.reshape(height, h // height, width, w // width, c).mean((1, 3))


def downsample_stderr(stderr, width, height):
    """Standard error of a block mean: sqrt(sum of squares) / pixels per block."""
    h, w, c = stderr.shape
    k = (h // height) * (w // width)
    return np.sqrt(downsample(stderr ** 2, width, height) * k) / k


def reference_problem(scene, width, height):
    """Why the scene's reference cannot be compared with a width x height render, or None.
    Only like with like: each render pixel must cover the same k x k block of reference
    pixels, so the field of view is the same (a non-square render of a square camera crops it)."""
    if scene.reference is None:
        return scene.info.get("reference_problem")
    h, w = scene.reference.shape[:2]
    if w % width or h % height or w // width != h // height:
        return (f"the reference is {w}x{h}; a {width}x{height} render sees another part of the scene "
                f"or cannot be averaged from it (use {w // max(1, w // width)}x{h // max(1, w // width)} or another "
                f"divisor of the same aspect ratio)")
    return None


def reference_at(scene, width, height):
    """(reference, reference_stderr) at width x height, or (None, None) if not available
    (reference_problem says why)."""
    if scene.reference is None or reference_problem(scene, width, height):
        return None, None
    try:
        return (downsample(scene.reference.astype(np.float64), width, height),
                downsample_stderr(scene.reference_stderr.astype(np.float64), width, height))
    except ValueError:
        return None, None


@dataclass
class ZTest:
    passed: bool
    alpha: float
    tests: int
    min_p: float
    threshold_p: float   # Bonferroni: alpha / tests
    worst_pixel: tuple
    worst_z: float
    mean_abs_z: float

    def __str__(self):
        return (f"z-test {'passed' if self.passed else 'FAILED'}: {self.tests} pixel-channels, "
                f"min p {self.min_p:.3g} vs alpha/N {self.threshold_p:.3g}, worst |z| {self.worst_z:.2f} "
                f"at {self.worst_pixel}, mean |z| {self.mean_abs_z:.3f}")


MIN_DEGREES_OF_FREEDOM = 10


def z_test(image, stderr, expected, expected_stderr, alpha=0.01, min_stderr=1e-12, dof=None):
    """Per-pixel z-test of image against expected, Bonferroni-corrected over all pixel-channels.

    `dof`: when the render's standard error comes from few independent passes (BDPT), the
    statistic follows Student's t with passes - 1 degrees of freedom rather than a normal
    (the reference's own error, from far more samples, is small next to ours). Fewer than
    MIN_DEGREES_OF_FREEDOM is refused: with 1 or 2 a t-test passes almost anything (a Cauchy
    tail gives |t| = 4000 a p-value of 1e-4), and a test that cannot fail checks nothing.

    z = (image - expected) / sqrt(stderr^2 + expected_stderr^2). Pixels where both standard
    errors vanish (e.g. black background in both) must match exactly and are not counted.
    Passes when the smallest two-sided p-value is above alpha / N: the chance that a correct
    renderer fails is at most alpha, whatever the number of pixels.
    """
    if dof is not None and dof < MIN_DEGREES_OF_FREEDOM:
        raise ValueError(f"{dof} degrees of freedom (passes - 1) are too few for a meaningful test; "
                         f"render more passes (at least {MIN_DEGREES_OF_FREEDOM + 1})")
    var = stderr ** 2 + expected_stderr ** 2
    diff = image - expected
    tested = var > min_stderr ** 2
    exact_mismatch = (~tested) & (np.abs(diff) > 1e-6)
    z = np.zeros_like(diff)
    z[tested] = diff[tested] / np.sqrt(var[tested])
    if not tested.any():
        p = np.ones(1)
    elif dof:
        p = student_t_two_sided_p(z[tested], dof)
    else:
        p = normal_two_sided_p(z[tested])
    n = int(tested.sum())
    worst = np.unravel_index(np.argmax(np.abs(z)), z.shape)
    threshold = bonferroni(alpha, n)
    return ZTest(bool(p.min() > threshold and not exact_mismatch.any()), alpha, n, float(p.min()),
                 threshold, tuple(int(i) for i in worst), float(np.abs(z).max()),
                 float(np.abs(z[tested]).mean()) if n else 0.0)


def relative_mean_error(image, expected):
    """Per-channel |mean(image) / mean(expected) - 1|."""
    a = np.asarray(image).reshape(-1, 3).mean(0)
    b = np.asarray(expected).reshape(-1, 3).mean(0)
    return np.abs(a / b - 1.0)


def hard_pixels(ref, ref_err, fraction=0.1):
    """The pixels that are hardest for a path tracer: the `fraction` with the largest relative
    standard error in the reference (itself a path-traced render: Mitsuba's path integrator).
    In cornell_spheres these are the caustics and the light seen through the spheres."""
    rel = (ref_err / np.maximum(ref, 1e-6)).mean(-1)
    rel[ref.mean(-1) <= 0] = 0.0
    return rel >= np.quantile(rel, 1.0 - fraction)
