"""Connection records summed per pixel on the device (cl/record_film.cl): BDPT's records and the
light tracer's splats become a pass's image there, and the host reads one float4 per pixel per
pass instead of every record (before: 93 to 306 bytes per sample, results/gpu.md).

The sums are exact integer sums of the records rounded to 2^-48 (FilmAccumulator,
toolkit/core/layout.py): the same records give the same bits in any order, on any device, with
64-bit atomics or without (`word_bits`). Any producer of (value, pixel) records can add to it:
BDPT's connect phases today, Metropolis's splats later.
"""
import numpy as np
import pyopencl as cl

from toolkit.core.layout import FILM_ACCUMULATOR, FILM_RECORDS_PER_ITEM
from toolkit.opencl import program

INT64_ATOMICS = "cl_khr_int64_base_atomics"


def film_word_bits(device):
    """The words the record film adds with on `device`: 64 where it has 64-bit atomics, else 32."""
    return 64 if INT64_ATOMICS in device.extensions.split() else 32


def film_path(device):
    """How the record film adds on `device`, in words (`python -m toolkit devices`)."""
    if film_word_bits(device) == 64:
        return f"exact 128-bit fixed-point sums with 64-bit atomics ({INT64_ATOMICS})"
    return f"exact 128-bit fixed-point sums with 32-bit atomics, carried across four words (no {INT64_ATOMICS})"


def unit_exponent_for(brightest):
    """The film's unit for a scene whose brightest emission is `brightest`: the exponent of the
    power of two at or above it (a record far brighter than any light is a bug, FILM_RECORD_LIMIT)."""
    return int(np.frexp(float(brightest))[1]) if brightest > 0 else 0


class RecordFilm:
    """The records of one pass, summed per pixel on `queue`'s device, for an image of `pixels`
    pixels: `add` each batch of records as it is written, `resolve` once the pass is done."""

    def __init__(self, queue, pixels, local_size=program.LOCAL_SIZE, sources=None, word_bits=None, unit_exponent=0):
        """`sources`: where the build finds cl/'s files (program.Sources; None: cl/). `word_bits`:
        32 or 64 (None: the device's, film_word_bits); both give the same image. `unit_exponent`:
        records are counted in units of 2^unit_exponent (unit_exponent_for: near the brightest
        light), so the film's precision follows the scene's brightness."""
        self.queue, self.pixels, self.local_size = queue, int(pixels), local_size
        self.unit_exponent = np.int32(unit_exponent)
        self.word_bits = film_word_bits(queue.device) if word_bits is None else int(word_bits)
        if self.word_bits not in (32, 64):
            raise ValueError(f"word_bits must be 32 or 64, got {word_bits!r}")
        built = program.build(queue, "record_film.cl", {"LOCAL_SIZE": local_size, "FILM_WORD_BITS": self.word_bits},
                              directory=sources)
        self.add_kernel = program.kernel(built, "record_film_add")
        self.resolve_kernel = program.kernel(built, "record_film_resolve")
        self._sums = self._image = None    # the device memory, made at the first use

    @property
    def sums(self):
        """FilmAccumulator[pixels]: the pass's sums so far, zero at the start."""
        if self._sums is None:
            size = FILM_ACCUMULATOR.dtype.itemsize * program.padded(self.pixels, self.local_size)
            self._sums = cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE, size)
            cl.enqueue_fill_buffer(self.queue, self._sums, np.uint32(0), 0, size)
        return self._sums

    @property
    def image(self):
        """float4[pixels]: the last resolved pass."""
        if self._image is None:
            self._image = cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE,
                                    16 * program.padded(self.pixels, self.local_size))
        return self._image

    def add(self, values, pixels, count, weighted=False):
        """Queue the addition of `count` records: `values` a buffer of float4 (RGB; with `weighted`,
        RGB and a weight in .w that multiplies it), `pixels` one of int (-1: no record there)."""
        if count:
            items = -(-count // FILM_RECORDS_PER_ITEM)
            program.launch(self.queue, self.add_kernel, items, values, pixels, np.int32(count),
                           np.int32(bool(weighted)), self.unit_exponent, np.int32(self.pixels), self.sums,
                           local_size=self.local_size)

    def resolve_on_device(self):
        """Queue the pass's image (`image`: float4 per pixel, RGB sums and, in .w, the records
        dropped there) and start the next pass at zero; returns the image's buffer, overwritten by
        the next pass's resolve (the queue is in order: what is queued before that reads this pass's)."""
        program.launch(self.queue, self.resolve_kernel, self.pixels, self.sums, self.unit_exponent,
                       np.int32(self.pixels), self.image, local_size=self.local_size)
        return self.image

    def resolve(self):
        """Queue the pass's image and its read, and start the next pass at zero: returns (the host's
        (pixels, 4) float32 array: RGB sums and, in column 3, the records dropped at each pixel;
        the read's event). Nothing waits: wait for the event before reading the array."""
        self.resolve_on_device()
        result = np.empty((self.pixels, 4), np.float32)
        return result, cl.enqueue_copy(self.queue, result, self.image, is_blocking=False)
