"""The film: per-pixel sums in float64 on the host, and a standard-error estimate.

A float32 accumulator stops growing after ~1e7 additions of similar values, so the device
only ever sums a handful of samples; everything else adds up here in float64. Every sample is
an independent estimate of its pixel, so the standard error is sqrt(sample variance / n).
"""
import numpy as np


def clamp_radiance(values, limit):
    """Firefly clamping (scene integrator.clamp, scenes/FORMAT.md): each RGB row of `values`
    whose largest component m exceeds `limit` is scaled by limit / m, so its colour is kept
    (pbrt-v4's maxcomponentvalue). `limit` None: unchanged. Non-finite rows stay as they are,
    so the film still counts and drops them. Biased: it removes energy, to remove variance."""
    if limit is None:
        return values
    rgb = values[..., :3]
    m = rgb.max(-1, keepdims=True)
    over = np.isfinite(m) & (m > limit)
    if over.any():
        values = values.copy()
        values[..., :3] = np.where(over, rgb * (limit / np.where(over, m, 1.0)), rgb)
    return values


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

    def add_pixel_major(self, radiance):
        """Samples laid out as (samples, pixels) in one array: the common case, without bincount."""
        per_pixel = radiance.reshape(-1, len(self.count), 4)
        if np.any(per_pixel[..., 3] != 0) or not np.isfinite(per_pixel[..., :3]).all():
            self._add_pixel_major_dropping(per_pixel)
            return
        # Every sample finite (the rule): one float64 row of pixels at a time, added in the order
        # value.sum(0) adds them, so the sums are bit for bit those of the general path below,
        # at a third of its time (no float64 copy of the whole pass; this runs on the host while
        # the device renders the next pass, and takes CPU time from it on a CPU device).
        total = per_pixel[0, :, :3].astype(np.float64)
        squares = total * total
        for row in per_pixel[1:]:
            value = row[:, :3].astype(np.float64)
            total += value
            value *= value
            squares += value
        self.sum += total
        self.sum_sq += squares
        self.count += per_pixel.shape[0]

    def _add_pixel_major_dropping(self, per_pixel):
        """add_pixel_major where some sample is flagged (.w != 0) or not finite: it is counted and left out."""
        value = per_pixel[..., :3].astype(np.float64)
        bad = (per_pixel[..., 3] != 0) | ~np.isfinite(value).all(-1)
        value[bad] = 0.0
        self.nonfinite_samples += int(np.count_nonzero(bad))
        self.sum += value.sum(0)
        self.sum_sq += (value ** 2).sum(0)
        self.count += per_pixel.shape[0]

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
