"""What every technique shares: the build of its kernel for a scene, and the render loop
that splits the sample budget into passes and feeds the film."""
import time

import numpy as np

from toolkit.opencl import program
from toolkit.opencl.device_model import resolve_warp_width
from toolkit.opencl.work_sizes import CPU_POOL_SIZE, CPU_STREAM_SIZE, check_fits, device_work_sizes
from toolkit.core.film import Film
from toolkit.opencl.film_reduce import FilmReduction
from toolkit.opencl.device_film import DeviceFilm, has_fp64
from toolkit.core.layout import LONGEST_SUBPATH
from toolkit.techniques.device_memory import DeviceMemory
from toolkit.techniques.kernels import Kernels
from toolkit.techniques.simd_recorder import SimdRecorder
from toolkit.core.validate import InputError, local_size as checked_local_size, whole_number


def pixel_count(camera):
    """The pixels of the image a Camera record is for (width x height): a pass of one sample per
    pixel is this many samples."""
    return int(camera["width"]) * int(camera["height"])


class Technique:
    """Base class. A technique sets `name`, `source` (its cl/ file) and implements `run_pass`.
    It sizes its work and runs the pass loop; its parts do the rest: `kernels` (its program and
    launches, kernels.py), `memory` (its device memory, device_memory.py) and `recorder` (its
    SIMD counters, simd_recorder.py)."""
    name = None
    source = None
    family = None    # "pt" (path tracing) or "bdpt" (bidirectional): what a technique's samples are
    # Work-items per launch we aim for: enough to fill a GPU, small enough to read back often.
    target_batch = 1 << 18
    _collecting = None   # (read event, what adds the pass to the film once read) of the pass queued last
    film_reduction = None   # the FilmReduction of collect, made at its first pass
    # Whether collect keeps a path tracer's film on the device (device_film.py); None: where the
    # device has float64. False: each pass's sums are read back and added on the host.
    film_on_device = None

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
        built = program.build(queue, self.source, defines, directory=self.sources, binary_cache=binary_cache)
        self.build_seconds = time.perf_counter() - start
        # Its parts: launching its kernels, its device memory, its SIMD counters.
        self.kernels = Kernels(queue, built, self.local_size, device_scene)
        self.memory = DeviceMemory(queue, self.local_size)
        self.recorder = SimdRecorder(warp_width, count_simd, queue, self.local_size, self.sources.toolkit_only())

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

    def by_turn(self, make):
        """What a step's SIMD counters read, one per turn: two buffers from make() when counting,
        so that a step's are summed with the next step's (simd_recorder.py StepPairs), else one
        buffer for both turns."""
        first = make()
        return (first, make() if self.count_simd else first)

    def extend_in_place(self, pass_args, length, paths, alive, hits, radiance, lane_counts):
        """The in-place extension step (cl/extend_in_place.h) over the first `length` slots of
        `paths`: trace into `hits`, then shade (multi-pass compaction's; pt_inplace_regen has kernels of
        its own that also regenerate, around the same per-slot code)."""
        k = self.kernels
        k.launch("extend_in_place_trace", length, **k.scene_args(), pass_args=pass_args,
                 stream_length=k.int32(length), paths=paths, alive=alive, hits=hits, lane_counts=lane_counts)
        k.launch("extend_in_place_shade", length, **k.scene_args(), pass_args=pass_args,
                 stream_length=k.int32(length), paths=paths, alive=alive, hits=hits, radiance=radiance,
                 lane_counts=lane_counts)

    def render(self, width, height, spp, seed=0, progress=None):
        """Render `spp` samples per pixel in passes; returns the film (see toolkit.api.render)."""
        film = Film(width, height)
        camera = self.scene.camera(width, height)
        self.begin_render(camera, np.uint32(seed), spp)
        per_pass = self.spp_per_pass(pixel_count(camera), spp)
        for start in range(0, spp, per_pass):
            count = min(per_pass, spp - start)
            self.run_pass(film, camera, np.uint32(seed), start, count)
            if progress is not None:
                progress.update(count)
        self.end_render(film)
        return film

    def begin_render(self, camera, seed, spp):
        """Before the first pass of a render of `spp` samples per pixel."""
        self._collecting = None   # a render stopped by an error leaves no pass for this one

    def end_render(self, film):
        """After the last pass: its samples reach the film (read from the device if kept there:
        a sample never written raises here)."""
        self.finish_collect()
        self.queue.finish()
        film.read_device()

    def spp_per_pass(self, pixels, spp):
        """Samples per pixel in one pass (one launch batch) of an image of `pixels` pixels."""
        if self.pass_spp is not None:
            return min(spp, self.pass_spp)
        return max(1, min(spp, self.target_batch // pixels))

    def run_pass(self, film, camera, seed, sample_base, spp):
        """One pass: samples sample_base .. sample_base + spp - 1 of every pixel, into `film`."""
        raise NotImplementedError

    def collect(self, film, buffer, n):
        """Sum the pass's `n` samples per pixel on the device (toolkit/opencl/film_reduce.py);
        every sample must have been written once. Where the device has float64 the sums are added
        to the film there (device_film.py) and nothing is read until the film is asked for.
        Else the read of the sums is queued behind the pass's kernels and they reach the film at
        the next collect (after the next pass's kernels are queued) or at finish_collect: so the
        host adds one pass to the film while the device runs the next, instead of the device
        waiting. The queue is in order, so the next pass's refill of `buffer` waits for the sums."""
        pixels = film.width * film.height
        if self.film_reduction is None:
            self.film_reduction = FilmReduction(self.queue, self.local_size, self.sources.toolkit_only())
        if self.film_on_device is None:
            self.film_on_device = has_fp64(self.queue.device)
        if self.film_on_device:
            if film.device is None:
                film.keep_on_device(DeviceFilm(self.queue, pixels, self.local_size, self.sources.toolkit_only(),
                                               owner=self.name))
            film.device.add(self.film_reduction.reduce_on_device(buffer, pixels, n // pixels, self.clamp),
                            n // pixels)
            film.add_device_pass(n // pixels)
            self.queue.flush()    # start the queued work now, not at the next wait
            return
        result, done = self.film_reduction.reduce(buffer, pixels, n // pixels, self.clamp)
        self.collect_later(done, lambda: self.add_pixel_sums(film, result, n // pixels))

    def collect_later(self, done, add_to_film):
        """A pass's sums are being read (event `done`): `add_to_film()` adds them once read, at
        the next pass's collect_later or at finish_collect, while the device runs the next pass."""
        self.queue.flush()    # start the queued work now, not at the next wait
        self.finish_collect()
        self._collecting = (done, add_to_film)

    def finish_collect(self):
        """Add the sums of the pass whose read collect_later queued (if any) to its film."""
        pending, self._collecting = self._collecting, None
        if pending is None:
            return
        done, add_to_film = pending
        done.wait()
        add_to_film()

    def add_pixel_sums(self, film, result, samples):
        """A path-tracing pass's FilmPixel sums (`samples` per pixel), read back, into `film`."""
        missing = int(result["missing"].sum())
        if missing:
            raise RuntimeError(f"{self.name}: {missing} of {samples * len(result)} samples were never written "
                               "(sample accounting bug)")
        film.add_pixel_sums(result["sum"][:, :3], result["sum_sq"][:, :3], samples, int(result["dropped"].sum()))

    def extra_stats(self):
        """Technique-specific figures added to the render stats (the work in flight, if chosen)."""
        return dict(getattr(self, "work_sizes", {}))

    def simd_efficiency(self):
        return self.recorder.efficiency()
