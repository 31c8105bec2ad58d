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

    source = "film_accumulate.cl"
    kernel_name = "film_accumulate"     # what `add` launches: a pass's FilmPixel sums

    @staticmethod
    def defines(local_size):
        """The defines its program is built with (the offline GPU build builds it so too)."""
        return {"LOCAL_SIZE": local_size}

    def __init__(self, queue, pixels, local_size=program.LOCAL_SIZE, sources=None, owner="a path tracer"):
        """`sources`: where the build finds cl/'s files (program.Sources; None: cl/)."""
        self.queue, self.pixels, self.local_size, self.owner = queue, int(pixels), local_size, owner
        built = program.build(queue, self.source, self.defines(local_size), directory=sources)
        self.kernel = program.kernel(built, self.kernel_name)
        context, flags = queue.context, cl.mem_flags.READ_WRITE
        size = program.padded(self.pixels, local_size)
        # per pixel: the sums of r, g, b and of their squares; the samples missing and dropped
        self.sums, self.counts = cl.Buffer(context, flags, 6 * 8 * size), cl.Buffer(context, flags, 2 * 4 * size)
        for buffer in (self.sums, self.counts):
            cl.enqueue_fill_buffer(queue, buffer, np.uint8(0), 0, buffer.size)
        self.samples = 0       # the samples added so far (all pixels): the error's figure
        self.args = (np.int32(self.pixels), self.sums, self.counts)

    def add(self, pass_sums, samples):
        """Queue the addition of a pass's FilmPixel buffer (`samples` samples per pixel); nothing waits."""
        self.samples += samples * self.pixels
        program.launch(self.queue, self.kernel, self.pixels, pass_sums, *self.args, local_size=self.local_size)

    def read(self):
        """(sums, sums of squares (pixels, 3) float64, the samples dropped as non-finite), behind the
        queued passes. Raises RuntimeError if a sample was never written (a sample-accounting bug)."""
        sums, counts = np.empty((self.pixels, 6)), np.empty((self.pixels, 2), np.int32)
        cl.enqueue_copy(self.queue, sums, self.sums, is_blocking=False)
        cl.enqueue_copy(self.queue, counts, self.counts, is_blocking=False)
        self.queue.finish()
        missing, dropped = counts.sum(0, dtype=np.int64)
        if missing:
            raise RuntimeError(f"{self.owner}: {missing} of {self.samples} samples were never written "
                               "(sample accounting bug)")
        return sums[:, :3].copy(), sums[:, 3:].copy(), int(dropped)


class DevicePassFilm(DeviceFilm):
    """A BDPT film kept on the device: each pass's image (RecordFilm.resolve_on_device: the RGB sums of
    its records per pixel, the records dropped in .w) is added as Film.add_pass adds it on the host,
    in float64 and in the same order (cl/film_accumulate.cl film_accumulate_pass): the same bits.
    `read` returns the passes' sums (of spp x mean and of spp x mean^2, per pixel) and the records
    dropped. Reading each pass's image back cost 16 bytes per pixel per pass: at 16 samples per pixel
    a pass, 1 byte per sample, ten times what issue 48 allows."""

    kernel_name = "film_accumulate_pass"

    def __init__(self, queue, pixels, local_size=program.LOCAL_SIZE, sources=None, owner="BDPT"):
        super().__init__(queue, pixels, local_size, sources, owner)

    def add(self, image, spp):
        """Queue the addition of a pass's resolved image of `spp` samples per pixel; nothing waits."""
        self.samples += spp * self.pixels
        program.launch(self.queue, self.kernel, self.pixels, image, np.int32(spp), *self.args,
                       local_size=self.local_size)
