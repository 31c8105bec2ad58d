"""A path tracer's film kept on the device across passes (cl/film_accumulate.cl): each pass's
FilmPixel sums (film_reduce.py) are added there in float64, and the host reads the film once,
when it is asked for (the end of a render, a frame of the demo), instead of every pass's sums.

Measured on this 2-core CPU at the H200's sizes (bench --host --gpu-sizes), reading each pass's
sums back and adding them on the host cost pt_naive 12 bytes and several ns of host CPU per sample,
more than an H200's kernels take for it (about 2 ns).

The same image bits as the host's film (toolkit/core/film.py): the device adds the same float32
pass sums in float64 in the same order. A device without float64 (no cl_khr_fp64) keeps the
host's film: `python -m toolkit devices` says which path a device takes (film_path).
"""
import numpy as np
import pyopencl as cl

from toolkit.opencl import program

FP64 = "cl_khr_fp64"


def has_fp64(device):
    """Whether `device` computes in float64 (cl_khr_fp64)."""
    return FP64 in device.extensions.split()


def film_path(device):
    """Where a path tracer's film adds its passes on `device`, in words (`python -m toolkit devices`)."""
    if has_fp64(device):
        return f"float64 sums kept on the device, read once at the end ({FP64})"
    return f"float64 sums on the host, each pass's sums read back (no {FP64})"


class DeviceFilm:
    """The float64 sums of a film of `pixels` pixels on `queue`'s device, zero at the start: `add`
    each pass's FilmPixel buffer, `read` the sums so far. `owner` names the technique in the error
    about a sample never written."""

    def __init__(self, queue, pixels, local_size=program.LOCAL_SIZE, sources=None, owner="a path tracer"):
        """`sources`: where the build finds cl/'s files (program.Sources; None: cl/)."""
        self.queue, self.pixels, self.local_size, self.owner = queue, int(pixels), local_size, owner
        built = program.build(queue, "film_accumulate.cl", {"LOCAL_SIZE": local_size}, directory=sources)
        self.kernel = program.kernel(built, "film_accumulate")
        context, flags = queue.context, cl.mem_flags.READ_WRITE
        size = program.padded(self.pixels, local_size)
        self.sums, self.sums_sq = (cl.Buffer(context, flags, 3 * 8 * size) for _ in range(2))
        self.missing, self.dropped = (cl.Buffer(context, flags, 4 * size) for _ in range(2))
        for buffer in (self.sums, self.sums_sq, self.missing, self.dropped):
            cl.enqueue_fill_buffer(queue, buffer, np.uint8(0), 0, buffer.size)
        self.samples = 0       # the samples added so far (all pixels): the error's figure
        self.args = (np.int32(self.pixels), self.sums, self.sums_sq, self.missing, self.dropped)

    def add(self, pass_sums, samples):
        """Queue the addition of a pass's FilmPixel buffer (`samples` samples per pixel); nothing waits."""
        self.samples += samples * self.pixels
        program.launch(self.queue, self.kernel, self.pixels, pass_sums, *self.args, local_size=self.local_size)

    def read(self):
        """(sums, sums of squares (pixels, 3) float64, the samples dropped as non-finite), behind the
        queued passes. Raises RuntimeError if a sample was never written (a sample-accounting bug)."""
        missing, dropped = np.empty(self.pixels, np.int32), np.empty(self.pixels, np.int32)
        sums, sums_sq = np.empty((self.pixels, 3)), np.empty((self.pixels, 3))
        for out, buffer in ((sums, self.sums), (sums_sq, self.sums_sq), (missing, self.missing),
                            (dropped, self.dropped)):
            cl.enqueue_copy(self.queue, out, buffer, is_blocking=False)
        self.queue.finish()
        never = int(missing.sum(dtype=np.int64))
        if never:
            raise RuntimeError(f"{self.owner}: {never} of {self.samples} samples were never written "
                               "(sample accounting bug)")
        return sums, sums_sq, int(dropped.sum(dtype=np.int64))
