"""The film: per-pixel sums in float64 on the host, and a standard-error estimate.

A float32 accumulator stops growing after ~1e7 additions of similar values, so the device
only sums one pass (with a compensated sum: cl/film_reduce.cl; BDPT's records as exact
integers: cl/record_film.cl);
the passes add up here in float64, or, on a device with float64, in the same order on the
device (toolkit/opencl/device_film.py: `keep_on_device`), read when the sums are asked for.
Every sample is an independent estimate of its pixel, so the
standard error is sqrt(sample variance / n).
"""
import numpy as np


class _ReadFromDevice:
    """A film's per-sample sum (`_name` holds it): read from the device first while the film keeps
    its sums there (Film.keep_on_device), so a reader always sees every pass so far."""

    def __set_name__(self, owner, name):
        self.held = "_" + name

    def __get__(self, film, owner=None):
        if film is None:
            return self
        film.read_device()
        return getattr(film, self.held)

    def __set__(self, film, value):
        setattr(film, self.held, value)


class Film:
    def __init__(self, width, height):
        self.width, self.height = width, height
        self._sum = np.zeros((height * width, 3))
        self._sum_sq = np.zeros((height * width, 3))
        self.count = np.zeros(height * width, np.int64)
        self._nonfinite_samples = 0
        self.device = None       # the sums kept on a device, if any (keep_on_device)
        self._device_read = True  # whether _sum, _sum_sq, _nonfinite_samples hold the device's latest sums
        self.passes = 0   # whole-image passes (add_pass) instead of per-sample sums
        self.pass_sum = np.zeros((height * width, 3))
        self.pass_sum_sq = np.zeros((height * width, 3))
        self.device_passes = False   # whether the device keeps the passes' sums (keep_passes_on_device)

    # The per-sample sums and the passes' sums: on the host, or read from the device when asked for.
    sum = _ReadFromDevice()
    sum_sq = _ReadFromDevice()
    pass_sum = _ReadFromDevice()
    pass_sum_sq = _ReadFromDevice()
    nonfinite_samples = _ReadFromDevice()    # samples dropped as non-finite (counted as zeros)

    def keep_on_device(self, device_sums):
        """From now on the per-sample sums live on a device: `device_sums.read()` returns (sums,
        sums of squares, samples dropped) of every pass so far (toolkit/opencl/device_film.py), and
        each pass adds there and calls add_device_pass. Only for a film with no sums yet."""
        if self.count.any() or self.device is not None:
            raise ValueError("a film's sums move to a device before its first pass, once")
        self.device = device_sums

    def keep_passes_on_device(self, device_passes):
        """As keep_on_device, for whole-image passes (add_pass): `device_passes.read()` returns the
        passes' sums (pass_sum, pass_sum_sq) and the samples dropped (toolkit/opencl/device_film.py
        DevicePassFilm), and each pass adds there and calls add_device_image_pass."""
        self.keep_on_device(device_passes)
        self.device_passes = True

    def add_device_image_pass(self, spp):
        """A whole-image pass of `spp` samples per pixel was added on the device (keep_passes_on_device)."""
        self.passes += 1
        self.count += spp
        self._device_read = False

    def add_device_pass(self, samples):
        """A pass of `samples` per pixel was added on the device (keep_on_device)."""
        self.count += samples
        self._device_read = False

    def read_device(self):
        """Bring the device's sums here, if it has passes not read yet; raises what the device's
        read raises (a sample never written)."""
        if self._device_read:
            return
        if self.device_passes:
            self._pass_sum, self._pass_sum_sq, self._nonfinite_samples = self.device.read()
        else:
            self._sum, self._sum_sq, self._nonfinite_samples = self.device.read()
        self._device_read = True

    def add_pixel_sums(self, sums, sums_sq, samples, dropped=0):
        """A pass summed per pixel (on the device: toolkit/opencl/film_reduce.py): the sums and
        the sums of squares of its finite samples (pixels, 3), `samples` per pixel of which
        `dropped` in all were left out as non-finite: they count as zeros, and DroppedSamplesWarning
        reports them (toolkit/api.py)."""
        if self.device is not None:
            raise ValueError("this film's sums are kept on a device (keep_on_device)")
        self.sum += sums
        self.sum_sq += sums_sq
        self.count += samples
        self.nonfinite_samples += int(dropped)

    def add_pass(self, image, spp, nonfinite=0):
        """A whole pass as one image of spp samples per pixel (techniques whose samples add to
        other pixels, like BDPT's light tracing): each pass is an independent estimate of the
        image. Passes may differ in size: a pass of n samples has variance sigma^2 / n, so
        passes are weighted by n and sigma^2 is estimated from their spread (see stderr)."""
        if self.device is not None:
            raise ValueError("this film's sums are kept on a device (keep_on_device)")
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
