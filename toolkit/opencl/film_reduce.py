"""A path-tracing pass's samples summed per pixel on the device (cl/film_reduce.cl), so the host
reads one FilmPixel per pixel instead of every sample.

Measured on an NVIDIA H200 (results/gpu.md): with every sample read back and summed on the host,
pt_compact_regen spent 4 ms in its kernels and over 60 ms on the host for 2.2 million samples, so
the host's sums hid every difference between the techniques. A CPU gains too: the sums ran on
the host's cores beside the device's work.
"""
import numpy as np
import pyopencl as cl

from toolkit.core.layout import FILM_PIXEL
from toolkit.opencl import program


class FilmReduction:
    """Sums a pass's pixel-major samples per pixel on `queue`'s device; one per technique."""

    def __init__(self, queue, local_size=program.LOCAL_SIZE, sources=None):
        """`sources`: where the build finds cl/'s files (program.Sources; None: cl/)."""
        self.queue = queue
        self.local_size = local_size
        built = program.build(queue, "film_reduce.cl", {"LOCAL_SIZE": local_size}, directory=sources)
        self.kernel = program.kernel(built, "film_reduce")
        self._sums = {}    # pixels -> the FilmPixel buffer, made once per image size

    def reduce(self, radiance, pixels, samples, clamp=None):
        """Queue the sums of `samples` samples per pixel in `radiance` (float4, pixel-major) and
        their read; returns (the host's FilmPixel array, the read's event). Nothing waits."""
        out = self.reduce_on_device(radiance, pixels, samples, clamp)
        result = FILM_PIXEL.zeros(pixels)
        return result, cl.enqueue_copy(self.queue, result, out, is_blocking=False)

    def reduce_on_device(self, radiance, pixels, samples, clamp=None):
        """Queue the sums as `reduce` does, without the read: returns the device's FilmPixel buffer
        (one per image size, refilled by the next pass: the queue is in order), for a DeviceFilm."""
        out = self._sums.get(pixels)
        if out is None:
            out = self._sums[pixels] = cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE,
                                                 FILM_PIXEL.dtype.itemsize * program.padded(pixels, self.local_size))
        limit = np.float32(np.inf if clamp is None else clamp)
        program.launch(self.queue, self.kernel, pixels, radiance, np.int32(pixels), np.int32(samples), limit, out,
                       local_size=self.local_size)
        return out
