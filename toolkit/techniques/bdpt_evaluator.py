"""BDPT's estimator over a pool of samples in flight: the random walk over compacted eye and
light streams with postponed regeneration (cl/bdpt_walk.h), and a connect phase whose records
go to a sink that the caller picks. bdpt_base.BdptTechnique gives the records to an image
(ImageSink); mlt keeps them with its chains.

One pass, read like the talk's slides:
    regenerate all samples;
    repeat:
        extend the eye stream and the light stream by one vertex each (compacted at once);
        when enough samples have terminated (default 60%):
            connect their subpaths (the connect phase), hand the records to the sink,
            then regenerate them.
The streams' lengths stay on the device (WalkCounter): a walk step reads them there, and the host
reads the counters behind the walk, LAG steps late (toolkit/techniques/pass_end.py), so it never
waits for a count before a launch; it learns that enough samples have terminated a few steps late
(the SIMD counters too are summed on the device: counting changes no step). It waits only at a connect
phase, for the terminated slots and the streams' lengths that regeneration appends to.
Light-tracing (t = 1) contributions land on other pixels: every connection writes a record
(pixel, value) on the device, and the sink decides where it goes: bdpt's ImageSink adds it to
the pass's image there (toolkit/opencl/record_film.py: exact integer sums, no float atomics),
mlt's reads its records back.
"""
import numbers
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import pyopencl as cl

from toolkit.core.layout import (LONGEST_SUBPATH, BDPT_PASS, BDPT_REGENERATION, BDPT_SLOT, BDPT_STEP, BDPT_VERTEX, CONNECT_ARGS, SUBPATH,
                                 SimdSum, WalkCounter)
from toolkit.core.scene import NO_LIMIT
from toolkit.opencl.compaction import Compactor
from toolkit.opencl.work_sizes import checked_size
from toolkit.techniques.base import Technique, pixel_count
from toolkit.techniques.device_memory import DeviceMemory
from toolkit.techniques.kernels import Kernels
from toolkit.techniques.pass_end import LAG
from toolkit.techniques.simd_recorder import SimdRecorder


WITHOUT_COMPACTION = "walk_without_compaction"   # the recorder's counter of the walk as it would be without compaction


def walk_defines(scene, longest, coalesced_scatter):
    """(MAX_VERTICES, the defines of the walk's kernels) for `scene`: subpaths of at most
    `longest` vertices when its depth is unbounded."""
    if coalesced_scatter not in (True, False):     # a string "false" would be true
        raise ValueError(f"coalesced_scatter must be true or false, got {coalesced_scatter!r}")
    # At least 2: the walk stores its first hit (vertex 1) before it checks the depth.
    max_vertices = max(2, min(longest, scene.max_depth + 1)) if scene.max_depth >= 0 else longest
    # Subpath roulette from half the scene's rr_depth (cl/bdpt_walk.h); never without one (a
    # general kernel has the roulette compiled in for every scene: Scene.features).
    rr_depth = (scene.rr_depth + 1) // 2 if scene.rr_depth >= 0 else NO_LIMIT
    return max_vertices, {"MAX_VERTICES": max_vertices, "COALESCED_SCATTER": bool(coalesced_scatter),
                          "BDPT_RR_DEPTH": rr_depth}


@dataclass
class SubpathStream:
    """One of the random walk's two streams: the subpaths still walking, packed at the start
    of `current` (a Subpath structure of arrays); each step compacts the survivors into `spare`."""
    is_light: int
    current: cl.Buffer
    spare: cl.Buffer
    vertices: cl.Buffer       # BdptVertex[pool][MAX_VERTICES]: every vertex stored so far
    length: int = 0           # at least the subpaths in the stream (their count is on the device): what a step launches

    def advance(self):
        """After a step: the survivors, compacted into `spare`, are the stream."""
        self.current, self.spare = self.spare, self.current


@dataclass
class SamplePool:
    """The device memory of a pool of samples in flight (made once per pool size)."""
    size: int
    capacity: int             # records per stream (size padded to the local size)
    eye: SubpathStream
    light: SubpathStream
    slots: cl.Buffer          # BdptSlot[size]: live state, sample id and vertex counts of each slot
    terminated: cl.Buffer     # int[size]: 1 where a sample waits for its connections (compaction flags)
    counters: cl.Buffer       # int[len(WalkCounter)]: each stream's length and survivors, terminated samples
    lane_counts: cl.Buffer    # LaneCounts[size]: one walk step or connect phase (COUNT_SIMD)
    all_slots: cl.Buffer      # 0 .. size - 1: the slot list of the first regeneration


@dataclass
class PassState:
    """One pass: the pool, the kernel arguments every launch shares, and the sample budget."""
    pool: SamplePool
    camera: np.void           # Camera record
    args: np.void             # BdptPass record (seed, sample_base, pool, capacity)
    budget: int               # samples in this pass
    sampler_args: dict = field(default_factory=dict)  # by name: the random-number kernels' extra (BDPT_SAMPLER_PARAM)
    next_id: int = 0          # next sample to start
    in_flight: int = 0        # slots whose sample is not connected yet
    reads: list = field(default_factory=list)   # the walk's counters, read behind it (oldest first)

    @property
    def pixels(self):
        return pixel_count(self.camera)


@dataclass
class Connections:
    """The records of one connect phase, on the device: what a sink adds up. The next connect
    phase reuses their buffers, so a sink uses them in `add`; `values` and `pixels` read them
    back (at their first use), for a sink that keeps them on the host."""
    count: int = 0                   # records
    value_buffer: cl.Buffer = None   # float4[count]: RGB, and with STRATEGY_IMAGES the MIS weight (RGB unweighted)
    pixel_buffer: cl.Buffer = None   # int[count]: the pixel each record lands on; -1: none (memory left unwritten)
    queue: cl.CommandQueue = None    # where they are read from
    strategy: np.ndarray = None      # (n,) each record's strategy (strategy_index), with STRATEGY_IMAGES
    slots: np.ndarray = None         # BdptSlot[pool] as connected (sample ids, vertex counts), if the phase reads them
    slot_records: np.ndarray = None  # (pool,) records each slot wrote, consecutive in slot order, likewise
    # The same on the device (the parallel connect phase): for a sink that sums each sample's records there
    slot_buffer: cl.Buffer = None    # BdptSlot[pool] as connected
    count_buffer: cl.Buffer = None   # int[pool]: records each slot wrote
    first_buffer: cl.Buffer = None   # int[pool]: where each slot's records start (the scan of count_buffer)

    @classmethod
    def none(cls):
        """A connect phase without records (no sample had terminated)."""
        return cls()

    @cached_property
    def values(self):
        """(n, 4) float32, read back."""
        return read_buffer(self.queue, self.value_buffer, np.empty((self.count, 4), np.float32))

    @cached_property
    def pixels(self):
        """(n,) int32, read back."""
        return read_buffer(self.queue, self.pixel_buffer, np.empty(self.count, np.int32))


@dataclass
class BdptContext:
    """What BDPT's evaluator and its connect phases use of a technique, and nothing more."""
    queue: cl.CommandQueue
    kernels: Kernels          # the technique's program (the walk's and connect phase's kernels) and its launches
    memory: DeviceMemory      # where the pool, the streams and the records are allocated
    recorder: SimdRecorder    # the technique's SIMD counters: the walk's steps count as its iterations
    compactor: Compactor      # compacts the streams and scans the connect phase's record counts


class BdptPoolTechnique(Technique):
    """A technique whose samples are BDPT samples of a pool (BdptEvaluator): the BDPT techniques,
    which add them into an image, and mlt, whose chains propose them. It builds the walk's kernels
    for the scene, sizes the pool for the device and makes its compactor; the subclass makes its
    evaluator with the connect phase it wants (self.bdpt)."""
    target_batch = 1 << 14      # samples per pass: many passes give the standard error
    max_vertices = LONGEST_SUBPATH   # per subpath when the depth is unbounded; paths this long carry ~1e-10 of the energy at albedo 0.7

    def __init__(self, queue, device_scene, defines, pool_size=None, coalesced_scatter=True, **kwargs):
        """`defines`: the subclass's own, added to the walk's (and to `extra_defines`, if given)."""
        self.max_vertices, walk = walk_defines(device_scene.scene, self.max_vertices, coalesced_scatter)
        walk.update(defines)
        walk.update(kwargs.pop("extra_defines", None) or {})
        checked_size("pool_size", pool_size)         # its range now, before the build; the device's memory after
        super().__init__(queue, device_scene, extra_defines=walk, **kwargs)
        # samples in flight (each stores MAX_VERTICES eye + light vertices); None: the device's
        self.pool_size = self.size_in_flight("pool_size", pool_size, self.max_vertices)
        compactor = Compactor(queue, local_size=self.local_size, sources=self.sources.toolkit_only())
        # What the evaluator and the connect phase get of this technique (not the technique itself).
        self.bdpt_context = BdptContext(queue, self.kernels, self.memory, self.recorder, compactor)
        self.bdpt = None            # the subclass's BdptEvaluator

    def extra_stats(self):
        return {**super().extra_stats(), **self.bdpt.stats()}


@dataclass
class BdptEvaluator:
    """The walk of BDPT's kernels (launched through `ctx`) and a connect phase:
    `connect(p, count)` evaluates the connections of the `count` terminated samples of pass `p`
    and returns their Connections."""
    ctx: BdptContext           # the kernels, memory, SIMD recorder and compactor of the technique that built them
    connect: object            # the connect phase: (PassState, count) -> Connections
    pool_size: int             # samples in flight
    regenerate_fraction: float  # connect (and regenerate) once this share of the samples in flight has terminated
    max_vertices: int          # per subpath (MAX_VERTICES)
    last_pass: PassState = None   # kept for inspection (tests, notebooks): the vertex memory of the last samples

    def __post_init__(self):
        fraction = self.regenerate_fraction
        if isinstance(fraction, bool) or not isinstance(fraction, numbers.Real) or not 0.0 < fraction <= 1.0:
            raise ValueError(f"regenerate_fraction must be a number in (0, 1], got {fraction!r}")

    def evaluate(self, p, sink):
        """Every sample of the pass's budget, through the pool; `sink.add` gets each connect phase's records."""
        self.regenerate(p, p.pool.all_slots, p.pool.size)        # every slot starts a sample
        while p.in_flight > 0:
            counters = self.walk(p)                               # one vertex more on every subpath
            if counters is not None and self.enough_terminated(p, counters):
                slots, count = self.terminated_slots(p)           # postponed regeneration:
                sink.add(self.connect(p, count))                  #   connect the terminated samples,
                self.regenerate(p, slots, count)                  #   then start new ones in their slots

    def enough_terminated(self, p, counters):
        """Whether the walk's `counters` (a step's, maybe some steps old) say it is time to connect:
        the share regenerate_fraction of the samples in flight has terminated, or every one has."""
        return (counters[WalkCounter.TERMINATED_SAMPLES] >= self.regenerate_fraction * p.in_flight
                or counters[WalkCounter.EYE_LENGTH] == counters[WalkCounter.LIGHT_LENGTH] == 0)

    # --- the stages of a pass, one kernel each ---------------------------------------------

    def start_pass(self, camera, seed, sample_base, budget, sampler_args=None, vector_stride=0):
        """The pass's state for `budget` samples; every slot of the pool starts terminated
        (nothing in flight). Kernels built with a sampler that reads stored primary-sample
        vectors (cl/mlt_proposals.h) take them as `sampler_args` (by parameter name), with their stride `vector_stride`
        (BdptPass.chains); plain BDPT has neither."""
        ctx = self.ctx
        pool = self.sample_pool(min(self.pool_size, budget))
        args = BDPT_PASS.record(seed=seed, sample_base=sample_base, pool=pool.size, capacity=pool.capacity,
                                chains=vector_stride)
        cl.enqueue_fill_buffer(ctx.queue, pool.counters, np.int32(0), 0, 4 * len(WalkCounter))
        pool.eye.length = pool.light.length = 0     # the streams' lengths: 0 here and on the device
        # every slot "terminated", nothing to connect
        self.last_pass = PassState(pool, camera, args, budget, dict(sampler_args or {}), in_flight=pool.size)
        return self.last_pass

    def sample_pool(self, size):
        """The streams, the vertex memory (tens of MB) and the per-slot arrays, made once per pool size."""
        ctx, mem = self.ctx, self.ctx.memory
        context, capacity = ctx.queue.context, mem.stream_capacity(size)
        ctx.compactor.reserve(size)   # its scratch memory too, once: no walk step or connect allocates
        vertex_bytes = BDPT_VERTEX.dtype.itemsize * size * self.max_vertices

        def stream(is_light):
            return SubpathStream(is_light, mem.soa_buffer(SUBPATH, size), mem.soa_buffer(SUBPATH, size),
                                 cl.Buffer(context, cl.mem_flags.READ_WRITE, vertex_bytes))
        return mem.reused(("pool", size), lambda: SamplePool(
            size, capacity, stream(0), stream(1),
            slots=cl.Buffer(context, cl.mem_flags.READ_WRITE, BDPT_SLOT.dtype.itemsize * mem.padded(size)),
            terminated=mem.int_buffer(size), counters=mem.int_buffer(len(WalkCounter)),
            lane_counts=mem.lane_counts_buffer(size),
            all_slots=cl.Buffer(context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                                hostbuf=np.arange(size, dtype=np.int32))))

    def regenerate(self, p, slots, count):
        """bdpt_regenerate: the `count` terminated slots listed in `slots` start the next
        samples of the budget (the rest go idle); the new subpaths join the end of the streams,
        whose lengths the host knows here (terminated_slots read them)."""
        ctx = self.ctx
        fresh = min(count, p.budget - p.next_id)
        if count:
            r = BDPT_REGENERATION.record(count=count, fresh=fresh, first_id=p.next_id,
                                         eye_base=p.pool.eye.length, light_base=p.pool.light.length)
            ctx.kernels.launch("bdpt_regenerate", count, **ctx.kernels.scene_args(), cam=p.camera,
                        pass_args=p.args, r=r, slot_list=slots, eye_stream=p.pool.eye.current,
                        light_stream=p.pool.light.current, eye_vertices=p.pool.eye.vertices,
                        light_vertices=p.pool.light.vertices, slots=p.pool.slots, **p.sampler_args)
        p.pool.eye.length += fresh
        p.pool.light.length += fresh
        p.next_id += fresh
        p.in_flight += fresh - count
        counters = p.pool.counters     # the new lengths on the device, and no sample terminated since
        for index, value in ((WalkCounter.TERMINATED_SAMPLES, 0), (WalkCounter.EYE_LENGTH, p.pool.eye.length),
                             (WalkCounter.LIGHT_LENGTH, p.pool.light.length)):
            cl.enqueue_fill_buffer(ctx.queue, counters, np.int32(value), 4 * index, 4)
        p.reads.clear()                # reads queued before this say nothing of the samples now in flight
        if ctx.recorder.on and fresh:
            ctx.recorder.stream_step("generate", fresh)

    def walk(self, p):
        """One random-walk step of both streams (bdpt_extend, compacted at once). Returns the walk's
        counters (WalkCounter) as read LAG steps ago, or None while no read is that old."""
        ctx = self.ctx
        counters = p.pool.counters
        cl.enqueue_fill_buffer(ctx.queue, counters, np.int32(0), 0, 4 * WalkCounter.TERMINATED_SAMPLES)
        for stream in (p.pool.eye, p.pool.light):
            if stream.length:
                self.extend(p, stream)
        # The survivors are the streams' next lengths: copied on the device (two ints, one copy).
        cl.enqueue_copy(ctx.queue, counters, counters, byte_count=8, src_offset=4 * WalkCounter.EYE_SURVIVORS,
                        dst_offset=4 * WalkCounter.EYE_LENGTH)
        p.reads.append(ctx.memory.read_later(counters, (np.int32, len(WalkCounter))))
        if len(p.reads) <= LAG:
            return None
        return self.lengths_known(p, p.reads.pop(0).result())

    def lengths_known(self, p, counters):
        """The streams can hold no more subpaths than a read of the counters says (they only shrink
        until the next regeneration): later steps launch over that many."""
        p.pool.eye.length = min(p.pool.eye.length, int(counters[WalkCounter.EYE_LENGTH]))
        p.pool.light.length = min(p.pool.light.length, int(counters[WalkCounter.LIGHT_LENGTH]))
        return counters

    def extend(self, p, stream):
        """bdpt_extend: one vertex more on every subpath of `stream` (the launch covers
        stream.length, the kernel reads the length on the device), survivors into its spare."""
        ctx = self.ctx
        step = BDPT_STEP.record(light_path=stream.is_light)
        ctx.kernels.launch("bdpt_extend", stream.length, **ctx.kernels.scene_args(), cam=p.camera,
                    pass_args=p.args, walk_step=step, stream=stream.current, next_stream=stream.spare,
                    counters=p.pool.counters, vertices=stream.vertices, slots=p.pool.slots,
                    lane_counts=p.pool.lane_counts, **p.sampler_args)
        self.count_walk_step(p, stream)
        stream.advance()

    def terminated_slots(self, p):
        """bdpt_mark_terminated, then compaction: (the list of terminated slots, its length). The
        host waits here, once per connect phase, for that length and for the streams' lengths."""
        ctx = self.ctx
        counters = ctx.memory.read_ints(p.pool.counters, len(WalkCounter))
        p.pool.eye.length = int(counters[WalkCounter.EYE_LENGTH])
        p.pool.light.length = int(counters[WalkCounter.LIGHT_LENGTH])
        ctx.kernels.launch("bdpt_mark_terminated", p.pool.size, pool=np.int32(p.pool.size),
                    slots=p.pool.slots, flags=p.pool.terminated)
        listed = ctx.memory.reused(("terminated_list", p.pool.size), lambda: ctx.memory.int_buffer(p.pool.size))
        return ctx.compactor.compact_indices(p.pool.terminated, p.pool.size, method="immediate", out=listed)

    # --- measuring and inspecting ------------------------------------------------------------

    def count_walk_step(self, p, stream):
        """SIMD counters of one walk step over `stream` (a no-op unless count_simd), summed on the
        device: its lanes are the first of the stream's length there (counters), its slots those of
        the subpaths it extended (for the walk as it would be without compaction)."""
        ctx = self.ctx
        if not ctx.recorder.on:
            return
        pool, draining = p.pool.size, p.next_id == p.budget

        def replay(recorder, sums):
            length = sums[SimdSum.LANES]
            if length == 0:
                return      # a step the host queued over a stream the device had found empty
            recorder.count_now("walk", length, numbered=True, capacity=pool, draining=draining)
            recorder.simd_counter().add_stream_step("compact", length)
            recorder.warp_loops(recorder.traversal_counter(), "closest", sums, "closest_steps")
            # without compaction each path keeps its slot's lane
            recorder.slot_warps(recorder.counter(WITHOUT_COMPACTION), "walk", sums, pool)
        length = WalkCounter.LIGHT_LENGTH if stream.is_light else WalkCounter.EYE_LENGTH
        ctx.recorder.lanes(replay, p.pool.lane_counts, 4, stream.length, length_at=p.pool.counters,
                           length_index=int(length), slot_of=stream.current,
                           slot_offset=SUBPATH.soa_offset("slot", p.pool.capacity) // 4, pool=pool)

    def stats(self):
        """The walk's figures for the render stats."""
        if not self.ctx.recorder.on:
            return {}
        self.ctx.recorder.flush()
        return {"walk_efficiency_without_compaction": self.ctx.recorder.counter(WITHOUT_COMPACTION).efficiency().get("walk")}

    def read_vertices(self):
        """The vertex memory of the last samples of the last pass, as numpy:
        (eye vertices, eye counts, light vertices, light counts), vertices shaped (pool, MAX_VERTICES)."""
        pool = self.last_pass.pool
        slots = self.ctx.memory.read_structs(BDPT_SLOT, pool.slots, pool.size)
        out = []
        for stream, counts in ((pool.eye, slots["eye_vertices"]), (pool.light, slots["light_vertices"])):
            v = np.empty(pool.size * self.max_vertices, BDPT_VERTEX.dtype)
            cl.enqueue_copy(self.ctx.queue, v, stream.vertices)
            out += [v.reshape(pool.size, self.max_vertices), counts.copy()]
        return tuple(out)


def read_buffer(queue, buffer, out):
    """`out` filled from the start of `buffer` (nothing read when it is empty)."""
    if out.size:
        cl.enqueue_copy(queue, out, buffer)
    return out


def scan_slot_counts(ctx, p, kernel, label):
    """Launch `kernel`, which writes a count per pool slot (records a connect phase will write),
    and scan the counts: (counts, firsts, total) with firsts[k] = sum of counts[0 .. k - 1].
    The buffers are kept under `label` and reused by the next connect phases."""
    pool = p.pool.size
    mem = ctx.memory
    counts, firsts = mem.reused((label, pool), lambda: (mem.int_buffer(pool), mem.int_buffer(pool)))
    ctx.kernels.launch(kernel, pool, pool=np.int32(pool), slots=p.pool.slots, counts=counts)
    firsts, total = ctx.compactor.exclusive_scan(counts, pool, out=firsts)
    return counts, firsts, total


def connect_args(p, firsts, values, pixels, lane_counts):
    """CONNECT_PARAMS by name (layout.py CONNECT_ARGS, in its order): what both connect kernels
    read (the scan of the slots' record counts, the pool, its vertices) and write (the records)."""
    given = dict(firsts=firsts, slots=p.pool.slots, eye_vertices=p.pool.eye.vertices,
                 light_vertices=p.pool.light.vertices, record_value=values, record_pixel=pixels,
                 lane_counts=lane_counts)
    return {name: given[name] for name, _ in CONNECT_ARGS}


def record_buffers(ctx, n, *more):
    """Device memory for n records (float4 values, int pixels, and `more(capacity)` buffers);
    it grows by powers of two and is reused by the next connect phases."""
    capacity = 1 << max(12, (n - 1).bit_length())
    return ctx.memory.reused(("records", capacity), lambda: (
        cl.Buffer(ctx.queue.context, cl.mem_flags.READ_WRITE, 16 * capacity), ctx.memory.int_buffer(capacity),
        *(make(capacity) for make in more)))


def per_pixel_sums(values, pixels, npix):
    """(npix, 3) float64 sums of RGB `values` by pixel index."""
    return np.stack([np.bincount(pixels, values[:, k], minlength=npix) for k in range(3)], axis=1)
