"""What every technique shares: the build of its kernel for a scene, and the render loop
that splits the sample budget into passes and feeds the film."""
import time

import numpy as np
import pyopencl as cl

from toolkit.opencl import program
from toolkit.opencl.device_model import resolve_warp_width
from toolkit.opencl.work_sizes import CPU_POOL_SIZE, CPU_STREAM_SIZE, check_fits, device_work_sizes
from toolkit.core.film import Film
from toolkit.opencl.film_reduce import FilmReduction
from toolkit.core.layout import LANE_COUNTS, LONGEST_SUBPATH, SCENE_PARAM_NAMES
from toolkit.core.simd import PhaseCounter
from toolkit.core.validate import InputError, local_size as checked_local_size, whole_number


def pixel_count(camera):
    """The pixels of the image a Camera record is for (width x height): a pass of one sample per
    pixel is this many samples."""
    return int(camera["width"]) * int(camera["height"])


class Technique:
    """Base class. A technique sets `name`, `source` (its cl/ file) and implements `run_pass`."""
    name = None
    source = None
    family = None    # "pt" (path tracing) or "bdpt" (bidirectional): what a technique's samples are
    # Work-items per launch we aim for: enough to fill a GPU, small enough to read back often.
    target_batch = 1 << 18
    # Whether shadow rays go to a queue traced by a kernel of their own (counted there).
    shadow_queue = False
    iterations = 0   # extension steps over all passes so far (for per-iteration plots)
    _collecting = None   # (film, host sums, read event, samples per pixel) of the pass collect queued last
    film_reduction = None   # the FilmReduction of collect, made at its first pass

    def __init__(self, queue, device_scene, warp_width=None, count_simd=True, extra_defines=None,
                 local_size=program.LOCAL_SIZE, general=False, pass_spp=None, sources=None, binary_cache=True):
        """`warp_width`: W of the SIMD counters; None: the device's (toolkit.opencl.device_model.device_warp_width).
        `general`: build the general kernel (every material and feature compiled in, Scene.features)
        instead of the one specialized to the scene; both compute the same image.
        `pass_spp` (an option of every technique): samples per pixel in one pass instead of what
        fills `target_batch`; a cost knob of the speed-accuracy study (toolkit/measure/study/).
        `sources` (an option of every technique): where `source` and its includes are found, a
        folder whose files replace cl/'s of the same name, or a program.Sources, which decides
        where each file comes from and may check what it reads; None: cl/ (program.default_sources).
        The technique's shared parts (compactor, film reduction) follow the same Sources on cl/.
        `binary_cache=False`: the technique's program is compiled from source, past pyopencl's binary
        cache (`bench --specialization` times builds so: toolkit/measure/specialization.py)."""
        self.pass_spp = None if pass_spp is None else whole_number("technique.pass_spp", pass_spp, "pass_spp")
        # Firefly clamping (scene integrator.clamp): applied where samples reach the film.
        self.clamp = device_scene.scene.clamp
        self.queue = queue
        self.scene = device_scene
        warp_width, self.warp_width_source = resolve_warp_width(warp_width, queue.device)
        self.warp_width = warp_width
        self.count_simd = count_simd
        # The work-group size: the program is built for it (LOCAL_SIZE) and every launch uses it.
        # Random numbers are keyed by sample, not by work-item, so it does not change the image.
        self.local_size = checked_local_size(local_size)
        if self.local_size > queue.device.max_work_group_size:
            raise InputError(f"local_size {self.local_size} exceeds the device's maximum work-group size "
                             f"{queue.device.max_work_group_size}")
        self.general = bool(general)
        defines = dict(device_scene.features(self.general))
        defines["COUNT_SIMD"] = bool(count_simd)
        defines.update(extra_defines or {})
        defines["LOCAL_SIZE"] = self.local_size
        self.defines = defines
        self.sources = sources if isinstance(sources, program.Sources) else program.default_sources(sources)
        start = time.perf_counter()
        self.program = program.build(queue, self.source, defines, directory=self.sources,
                                     binary_cache=binary_cache)
        self.build_seconds = time.perf_counter() - start
        self.simd = PhaseCounter(warp_width)
        self.traversal = PhaseCounter(warp_width)

    def size_in_flight(self, option, given, max_vertices=LONGEST_SUBPATH):
        """The work a stream technique keeps in flight (option "stream_size" or "pool_size"):
        `given` (checked: the device must hold its buffers, toolkit.opencl.work_sizes.check_fits), else
        the device's choice (toolkit.opencl.work_sizes.choose_work_sizes: a GPU's resident
        work-items, a CPU's own sizes).
        The pass grows with it (target_batch), so every slot still runs several samples a pass."""
        if given is not None:
            size, why = check_fits(self.queue.device, option, given, max_vertices), "given"
        else:
            chosen = device_work_sizes(self.queue.device, max_vertices)
            size, why = getattr(chosen, option), chosen.why
        reference = CPU_STREAM_SIZE if option == "stream_size" else CPU_POOL_SIZE
        self.target_batch = type(self).target_batch * max(1, -(-size // reference))
        self.work_sizes = {option: size, "work_sizes_source": why}
        return size

    def kernel(self, name):
        """The kernel object, retrieved once (each retrieval makes a new cl.Kernel)."""
        return program.kernel(self.program, name)

    def launch(self, kernel, n, /, *args, **named):
        """program.launch over n work-items in work-groups of this technique's local size (its
        program's LOCAL_SIZE). Arguments given by name follow the positional ones: the names are
        the kernel's own parameter names, in its order (tests/test_kernel_args.py checks them)."""
        return program.launch(self.queue, kernel, n, *args, *named.values(), local_size=self.local_size)

    def extend_in_place(self, pass_args, length, paths, alive, hits, radiance, lane_counts):
        """The in-place extension step (cl/extend_in_place.h) over the first `length` slots of
        `paths`: trace into `hits`, then shade; pt_inplace_regen and multi-pass compaction share it."""
        self.launch(self.kernel("extend_in_place_trace"), length, **self.scene_args(), pass_args=pass_args,
                    stream_length=np.int32(length), paths=paths, alive=alive, hits=hits, lane_counts=lane_counts)
        self.launch(self.kernel("extend_in_place_shade"), length, **self.scene_args(), pass_args=pass_args,
                    stream_length=np.int32(length), paths=paths, alive=alive, hits=hits, radiance=radiance,
                    lane_counts=lane_counts)

    def scene_args(self):
        """The scene's kernel arguments (SCENE_PARAMS) by parameter name, for launch(**...)."""
        return dict(zip(SCENE_PARAM_NAMES, self.scene.args()))

    def padded(self, n):
        """n rounded up to a multiple of this technique's local size (a launch's global size)."""
        return program.padded(n, self.local_size)

    def render(self, width, height, spp, seed=0, progress=None):
        """Render `spp` samples per pixel; returns the film (see toolkit.api.render)."""
        film = Film(width, height)
        self._collecting = None   # a render stopped by an error leaves no pass for this one
        camera = self.scene.camera(width, height)
        per_pass = self.spp_per_pass(pixel_count(camera), spp)
        start = 0
        while start < spp:
            count = min(per_pass, spp - start)
            self.run_pass(film, camera, np.uint32(seed), start, count)
            start += count
            if progress is not None:
                progress.update(count)
        self.finish_collect()
        self.queue.finish()
        return film

    def spp_per_pass(self, pixels, spp):
        """Samples per pixel in one pass (one launch batch) of an image of `pixels` pixels."""
        if self.pass_spp is not None:
            return min(spp, self.pass_spp)
        return max(1, min(spp, self.target_batch // pixels))

    def run_pass(self, film, camera, seed, sample_base, spp):
        raise NotImplementedError

    # --- helpers shared by the techniques -------------------------------------------------

    def output_buffer(self, n):
        """One float4 per sample of the pass, pre-filled with .w = -1 ("not written yet"); made
        once per pass size and refilled by every pass (the in-order queue runs collect's read of it first)."""
        buf = self.reused(("output", n), lambda: cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE,
                                                            16 * self.padded(n)))
        cl.enqueue_fill_buffer(self.queue, buf, np.array([0, 0, 0, -1], np.float32), 0, 16 * self.padded(n))
        return buf

    def collect(self, film, buffer, n):
        """Sum the pass's `n` samples per pixel on the device (toolkit/opencl/film_reduce.py) and
        queue the read of the sums, behind the pass's kernels; every sample must have been
        written once. The sums reach the film at the next collect (after the next pass's kernels
        are queued) or at finish_collect: so the host adds one pass to the film while the device
        runs the next, instead of the device waiting. The queue is in order, so the next pass's
        refill of `buffer` waits for the sums."""
        pixels = film.width * film.height
        if self.film_reduction is None:
            self.film_reduction = FilmReduction(self.queue, self.local_size, self.sources.toolkit_only())
        result, done = self.film_reduction.reduce(buffer, pixels, n // pixels, self.clamp)
        self.queue.flush()    # start the queued work now, not at the next wait
        self.finish_collect()
        self._collecting = (film, result, done, n // pixels)

    def finish_collect(self):
        """Add the pixel sums of the pass whose read collect queued (if any) to its film."""
        pending, self._collecting = self._collecting, None
        if pending is None:
            return
        film, result, done, samples = pending
        done.wait()
        missing = int(result["missing"].sum())
        if missing:
            raise RuntimeError(f"{self.name}: {missing} of {samples * len(result)} samples were never written "
                               "(sample accounting bug)")
        film.add_pixel_sums(result["sum"][:, :3], result["sum_sq"][:, :3], samples, int(result["dropped"].sum()))

    def reused(self, key, make):
        """Device memory that keeps its size from pass to pass (streams, vertex memory) is made
        once per technique: `key` names it with its size, `make()` allocates it."""
        cache = self.__dict__.setdefault("_reused", {})
        if key not in cache:
            cache[key] = make()
        return cache[key]

    def int_buffer(self, n, fill=None):
        buf = cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE, 4 * max(1, self.padded(n)))
        if fill is not None:
            self.fill_ints(buf, fill)
        return buf

    def fill_ints(self, buffer, value):
        """Set every int of `buffer` to `value` (on the device, queued)."""
        cl.enqueue_fill_buffer(self.queue, buffer, np.int32(value), 0, buffer.size)

    def lane_counts_buffer(self, n):
        """One LaneCounts record per work-item (toolkit/core/layout.py), written when COUNT_SIMD."""
        return cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE,
                         LANE_COUNTS.dtype.itemsize * self.padded(max(n, 1)))

    def read_lane_counts(self, buffer, n):
        return self.read_structs(LANE_COUNTS, buffer, n)

    def read_structs(self, record, buffer, n, offset=0):
        """n records of layout `record` from `buffer` (starting `offset` bytes in)."""
        out = record.zeros(n)
        if n:
            cl.enqueue_copy(self.queue, out, buffer, src_offset=offset)
        return out

    def soa_buffer(self, record, n):
        """A stream of n records as a structure of arrays in one buffer; its capacity (what the
        kernels take with it) is n padded to the local size: see stream_capacity()."""
        return record.soa_buffer(self.queue.context, self.stream_capacity(n))

    def stream_capacity(self, n):
        return self.padded(n)

    def read_ints(self, buffer, n, columns=1):
        out = np.empty((n, columns) if columns > 1 else n, np.int32)
        if n:
            cl.enqueue_copy(self.queue, out, buffer)
        return out

    def count_stream_step(self, lanes, capacity, draining=False):
        """SIMD counters of one extension step over a stream, from the LaneCounts of the lanes
        that ran it; `capacity` is the stream's size (for the occupancy plot), `draining` whether
        the pass's budget is spent (no sample left to start: the final drain)."""
        self.simd.add_stream_step("extend", lanes["work"] > 0, iteration=self.iterations, capacity=capacity,
                                  draining=draining)
        self.iterations += 1
        self.traversal.add_warp_loops("closest", lanes["closest_steps"])
        if not self.shadow_queue:   # shadow rays traced inside the extension step
            self.simd.add_stream_step("shadow", lanes["shadow_rays"] > 0)
            self.traversal.add_warp_loops("shadow", lanes["shadow_steps"])

    def extra_stats(self):
        """Technique-specific figures added to the render stats (the work in flight, if chosen)."""
        return dict(getattr(self, "work_sizes", {}))

    def simd_efficiency(self):
        return self.simd.efficiency() if self.count_simd else {}
