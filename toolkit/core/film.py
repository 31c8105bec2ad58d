"""The film: per-pixel sums in float64 on the host, and a standard-error estimate.

A float32 accumulator stops growing after ~1e7 additions of similar values, so the device
only sums one pass (with a compensated sum: cl/film_reduce.cl; BDPT's records as exact
integers: cl/record_film.cl);
the passes add up here in float64. Every sample is an independent estimate of its pixel, so the
standard error is sqrt(sample variance / n).
"""
import numpy as np


class Film:
    def __init__(self, width, height):
        self.width, self.height = width, height
        self.sum = np.zeros((height * width, 3))
        self.sum_sq = np.zeros((height * width, 3))
        self.count = np.zeros(height * width, np.int64)
        self.nonfinite_samples = 0
        self.passes = 0   # whole-image passes (add_pass) instead of per-sample sums
        self.pass_sum = np.zeros((height * width, 3))
        self.pass_sum_sq = np.zeros((height * width, 3))

    def add_pixel_sums(self, sums, sums_sq, samples, dropped=0):
        """A pass summed per pixel (on the device: toolkit/opencl/film_reduce.py): the sums and
        the sums of squares of its finite samples (pixels, 3), `samples` per pixel of which
        `dropped` in all were left out as non-finite: they count as zeros, and DroppedSamplesWarning
        reports them (toolkit/api.py)."""
        self.sum += sums
        self.sum_sq += sums_sq
        self.count += samples
        self.nonfinite_samples += int(dropped)

    def add_pass(self, image, spp, nonfinite=0):
        """A whole pass as one image of spp samples per pixel (techniques whose samples add to
        other pixels, like BDPT's light tracing): each pass is an independent estimate of the
        image. Passes may differ in size: a pass of n samples has variance sigma^2 / n, so
        passes are weighted by n and sigma^2 is estimated from their spread (see stderr)."""
        value = image.reshape(-1, 3).astype(np.float64)
        self.passes += 1
        self.pass_sum += spp * value
        self.pass_sum_sq += spp * value ** 2
        self.count += spp
        self.nonfinite_samples += int(nonfinite)

    @property
    def degrees_of_freedom(self):
        """For the t-distribution of (mean - expected) / stderr: passes - 1, or None when the
        error comes from per-sample variance (many degrees of freedom: normal)."""
        return self.passes - 1 if self.passes else None

    @property
    def samples(self):
        return int(self.count.sum())

    def image(self):
        if self.passes:
            return (self.pass_sum / self.count[:, None]).reshape(self.height, self.width, 3)
        n = np.maximum(self.count, 1)[:, None]
        return (self.sum / n).reshape(self.height, self.width, 3)

    def stderr(self):
        if self.passes:
            # sigma^2 per sample from sum_i n_i (x_i - mean)^2 / (k - 1); the mean of N samples has sigma^2 / N.
            n = self.count[:, None].astype(np.float64)
            mean = self.pass_sum / n
            sigma2 = np.maximum(self.pass_sum_sq - n * mean ** 2, 0.0) / max(self.passes - 1, 1)
            return np.sqrt(sigma2 / n).reshape(self.height, self.width, 3)
        n = np.maximum(self.count, 1)[:, None]
        mean = self.sum / n
        var = np.maximum(self.sum_sq / n - mean ** 2, 0.0) * (n / np.maximum(n - 1, 1))
        return np.sqrt(var / n).reshape(self.height, self.width, 3)
