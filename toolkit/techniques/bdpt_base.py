"""What both bidirectional path tracers share: the random-walk phase over compacted eye and
light streams with postponed regeneration (cl/bdpt_walk.h), and the pass loop.

One pass, read like the talk's slides:
    regenerate all samples;
    repeat:
        extend the eye stream and the light stream by one vertex each (compacted at once);
        when enough samples have terminated (default 60%):
            connect their subpaths (the technique's connect phase), then regenerate them.
Light-tracing (t = 1) contributions land on other pixels: every connection writes a record
(pixel, value) and the host adds the records up per pixel in float64 (no float atomics on
the device). So a pass is an image, and the standard error comes from independent passes.
"""
import numpy as np
import pyopencl as cl

from .. import program
from ..compaction import Compactor
from ..layout import BDPT_VERTEX, SUBPATH
from ..simd import PhaseCounter
from .base import Technique


class BdptTechnique(Technique):
    pool_size = 1 << 12         # samples in flight (each has MAX_VERTICES eye + light vertices stored)
    target_batch = 1 << 14      # samples per pass: many passes give the standard error
    max_vertices = 64           # per subpath when the depth is unbounded; paths this long carry ~1e-10 of the energy at albedo 0.7

    def __init__(self, queue, device_scene, regenerate_fraction=0.6, coalesced_scatter=True, pool_size=None,
                 **kwargs):
        scene = device_scene.scene
        # At least 2: the walk stores its first hit (vertex 1) before it checks the depth.
        self.max_vertices = max(2, min(self.max_vertices, scene.max_depth + 1)) if scene.max_depth >= 0 else self.max_vertices
        defines = {"MAX_VERTICES": self.max_vertices, "COALESCED_SCATTER": bool(coalesced_scatter),
                   "BDPT_RR_DEPTH": (scene.rr_depth + 1) // 2}   # subpath roulette: see cl/bdpt_walk.h
        defines.update(kwargs.pop("extra_defines", None) or {})
        super().__init__(queue, device_scene, extra_defines=defines, **kwargs)
        if not 0.0 < regenerate_fraction <= 1.0:
            raise ValueError("regenerate_fraction must be in (0, 1]")
        self.regenerate_fraction = regenerate_fraction
        self.coalesced_scatter = coalesced_scatter
        self.pool_size = pool_size or self.pool_size
        self.compactor = Compactor(queue)
        self.uncompacted = PhaseCounter(self.warp_width)   # the walk as it would be without compaction

    def run_pass(self, film, camera, seed, sample_base, spp):
        ctx, q = self.queue.context, self.queue
        width, height = int(camera["width"]), int(camera["height"])
        budget = width * height * spp
        pool = min(self.pool_size, budget)
        mv = self.max_vertices
        # The streams, the vertex memory (tens of MB) and the per-slot arrays are made once per
        # pool size, not per pass.
        vertex_bytes = BDPT_VERTEX.dtype.itemsize * pool * mv
        buffers = self.reused(("pool", pool), lambda: dict(
            streams=[SUBPATH.soa_buffers(ctx, pool) for _ in range(4)],
            eye_vertices=cl.Buffer(ctx, cl.mem_flags.READ_WRITE, vertex_bytes),
            light_vertices=cl.Buffer(ctx, cl.mem_flags.READ_WRITE, vertex_bytes),
            slot_arrays=[self.int_buffer(pool) for _ in range(5)],   # eye/light counts, live, sample ids, flags
            counters=self.int_buffer(3),       # eye survivors, light survivors, terminated samples
            lane_counts=[self.lane_counts_buffer(pool) for _ in range(2)],   # eye, light
            all_slots=cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                                hostbuf=np.arange(pool, dtype=np.int32))))
        eye_stream, eye_spare, light_stream, light_spare = buffers["streams"]
        self.eye_vertices, self.light_vertices = buffers["eye_vertices"], buffers["light_vertices"]
        eye_count, light_count, live, sample_ids, flags = buffers["slot_arrays"]
        counters, lane_counts = buffers["counters"], buffers["lane_counts"]
        cl.enqueue_fill_buffer(q, live, np.int32(-1), 0, 4 * pool)
        cl.enqueue_fill_buffer(q, counters, np.int32(0), 0, 12)
        image = np.zeros((width * height, 3))
        self.pass_nonfinite = 0
        state = dict(eye_count=eye_count, light_count=light_count, live=live, sample_ids=sample_ids,
                     pool=pool, camera=camera, seed=seed, lane_counts=lane_counts[0])
        self.last_pass = state   # kept for inspection (tests, notebooks): the vertex memory of the last samples

        # All slots start "terminated": regenerate the whole pool.
        fresh = min(pool, budget)
        self.regenerate(state, buffers["all_slots"], pool, fresh, 0, sample_base, eye_stream, 0, light_stream, 0)
        eye_len = light_len = fresh
        next_id, in_flight = fresh, fresh
        extend = self.kernel("bdpt_extend")
        while in_flight > 0:
            # Random walk: one vertex more on every eye and light subpath, compacted at once.
            cl.enqueue_fill_buffer(q, counters, np.int32(0), 0, 8)    # the survivor counts
            for is_light, length, stream, spare in ((0, eye_len, eye_stream, eye_spare),
                                                    (1, light_len, light_stream, light_spare)):
                if length:
                    program.launch(q, extend, length, *self.scene.args(), camera, seed, np.int32(is_light),
                                   np.int32(length), *stream, *spare, counters,
                                   self.light_vertices if is_light else self.eye_vertices,
                                   light_count if is_light else eye_count, live, sample_ids,
                                   np.int32(sample_base), lane_counts[is_light])
            eye_survivors, light_survivors, done = self.read_ints(counters, 3)
            if self.count_simd:
                for is_light, length in ((0, eye_len), (1, light_len)):
                    if length:
                        self.count_walk_step(lane_counts[is_light], length, pool)
            if eye_len:
                eye_stream, eye_spare, eye_len = eye_spare, eye_stream, int(eye_survivors)
            if light_len:
                light_stream, light_spare, light_len = light_spare, light_stream, int(light_survivors)
            # Postponed regeneration: connect and restart once enough samples have terminated.
            if done >= self.regenerate_fraction * in_flight or (eye_len == 0 and light_len == 0):
                program.launch(q, self.kernel("bdpt_mark_terminated"), pool, np.int32(pool), live, flags)
                slots, count = self.compactor.compact_indices(flags, pool, method="immediate")
                image += self.connect(state, slots, count)
                fresh = min(count, budget - next_id)
                self.regenerate(state, slots, count, fresh, next_id, sample_base,
                                eye_stream, eye_len, light_stream, light_len)
                eye_len += fresh
                light_len += fresh
                next_id += fresh
                in_flight += fresh - count
                cl.enqueue_fill_buffer(q, counters, np.int32(0), 8, 4)   # terminated samples
        film.add_pass(image.reshape(height, width, 3) / spp, spp, nonfinite=self.pass_nonfinite)

    def count_walk_step(self, lane_counts, length, pool):
        """SIMD counters of one walk step over a stream of `length` subpaths (lanes: active,
        traversal steps, pool slot)."""
        lanes = self.read_ints(lane_counts, length, 4)
        self.simd.add_stream_step("walk", length, iteration=self.iterations, capacity=pool)
        self.iterations += 1
        self.simd.add_stream_step("compact", length)
        self.traversal.add_warp_loops("closest", lanes[:, 1])
        mask = np.zeros(pool, bool)      # without compaction each path keeps its slot's lane
        mask[lanes[:, 2]] = True
        self.uncompacted.add_stream_step("walk", mask)

    def regenerate(self, state, slots, count, fresh, first_id, sample_base, eye_stream, eye_base,
                   light_stream, light_base):
        if count == 0:
            return
        program.launch(self.queue, self.kernel("bdpt_regenerate"), count, *self.scene.args(), state["camera"],
                       state["seed"], np.int32(count), np.int32(fresh), slots, np.int32(first_id),
                       np.int32(sample_base), *eye_stream, np.int32(eye_base), *light_stream, np.int32(light_base),
                       self.eye_vertices, self.light_vertices, state["eye_count"], state["light_count"],
                       state["live"], state["sample_ids"])
        if self.count_simd and fresh:
            self.simd.add_stream_step("generate", fresh)

    def connect(self, state, slots, count):
        """Evaluate the connections of the `count` terminated samples listed in `slots`;
        returns their contributions per pixel (float64)."""
        raise NotImplementedError

    def reduce_records(self, values, pixels, npix):
        """Add connection records (value, pixel) per pixel in float64; non-finite ones are counted and dropped."""
        ok = pixels >= 0
        v, p = values[ok, :3], pixels[ok]
        sums = per_pixel_sums(v, p, npix)
        if np.isfinite(sums).all():      # a non-finite record would show in its pixel's sum
            return sums
        finite = np.isfinite(v).all(1)
        self.pass_nonfinite += int((~finite).sum())
        return per_pixel_sums(v[finite], p[finite], npix)

    def read_records(self, value_buffer, pixel_buffer, n):
        values = np.empty((n, 4), np.float32)
        pixels = np.empty(n, np.int32)
        if n:
            cl.enqueue_copy(self.queue, values, value_buffer)
            cl.enqueue_copy(self.queue, pixels, pixel_buffer)
        return values, pixels

    def extra_stats(self):
        stats = super().extra_stats()
        if self.count_simd:
            stats["walk_efficiency_without_compaction"] = self.uncompacted.efficiency().get("walk")
        return stats

    def read_vertices(self):
        """The vertex memory of the last samples of the last pass, as numpy:
        (eye vertices, eye counts, light vertices, light counts), vertices shaped (pool, MAX_VERTICES)."""
        state = self.last_pass
        pool = state["pool"]
        out = []
        for buffer, counts in ((self.eye_vertices, state["eye_count"]), (self.light_vertices, state["light_count"])):
            v = np.empty(pool * self.max_vertices, BDPT_VERTEX.dtype)
            cl.enqueue_copy(self.queue, v, buffer)
            out += [v.reshape(pool, self.max_vertices), self.read_ints(counts, pool)]
        return tuple(out)


def per_pixel_sums(values, pixels, npix):
    """(npix, 3) float64 sums of RGB `values` by pixel index."""
    return np.stack([np.bincount(pixels, values[:, k], minlength=npix) for k in range(3)], axis=1)
