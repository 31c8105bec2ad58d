"""BDPT's estimator over a pool of samples in flight: the random walk over compacted eye and
light streams with postponed regeneration (cl/bdpt_walk.h), and a connect phase whose records
go to a sink that the caller picks. bdpt_base.BdptTechnique gives the records to an image
(ImageSink); mlt keeps them with its chains.

One pass, read like the talk's slides:
    regenerate all samples;
    repeat:
        extend the eye stream, then the light stream, by one vertex each (compacted at once);
        when enough samples have terminated (default 60%; once the budget is spent, all):
            list them, connect their subpaths (the connect phase), hand the records to the sink,
            then regenerate them.
The counts stay on the device, and the host never waits for one before a launch: a walk step
reads the streams' lengths there (a ring of counts, WalkCounter: no step needs the host to clear
or copy one), and whether enough samples have terminated is decided there too. The host lists the
terminated samples on the device (the connect phase's record counts; bdpt_mark_terminated, which
marks them only if enough have terminated; the scan of their records and the list of their slots,
cl/bdpt_walk.h), queues one read of the counts it needs (listed samples, records, the streams'
lengths) and goes on walking: LAG steps later it has them without the device having waited, and
queues the connect phase and the regeneration (or, if too few had terminated, lists again).
It lists a few steps after a regeneration (listing_delay), and again after 0, 1, 2, 4, ... steps
while too few have terminated, so a connect phase costs a read or a few (toolkit/techniques/
pass_end.py says why reads are looked at late). Once the budget is spent (the drain) nothing is
left to regenerate, so the 60% rule has nothing to gain: the drain lists once, when every sample
in flight has terminated (a tail of ever smaller connect phases cost BDPT 7 more listings, each
four launches and a read, per pass of 270,336 samples: issue 48). That listing (mlt's only one:
its pool holds every chain) comes when the walk has ended: as
long after the pass's start as the longest of the last passes' walks (the device counts their
steps), and never later than the step by which every subpath has ended (MAX_VERTICES - 1 after the
last samples started), where it lists again if it was too early. A walk step past the end costs
two launches, a listing too early four and a read.
Every launch costs a GPU's host time (issue 48): a walk step is one launch per stream (one kernel
extending both would take 20 arguments), a listing four and a read, a connect phase one launch, a
regeneration one per stream, and a pass clears nothing but its counters at its start.
The samples that terminate meanwhile wait for the next connect phase (SLOT_TERMINATED; the listed
ones are SLOT_CONNECTING); regeneration appends to the streams after the lengths on the device.
The SIMD counters too are summed on the device: counting changes no step.
Light-tracing (t = 1) contributions land on other pixels: every connection writes a record
(pixel, value) on the device, and the sink decides where it goes: bdpt's ImageSink adds it to
the pass's image there (toolkit/opencl/record_film.py: exact integer sums, no float atomics),
mlt's stores them with their chains on the device.
"""
import math
import numbers
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import pyopencl as cl

from toolkit.core.layout import (LONGEST_SUBPATH, BDPT_PASS, BDPT_REGENERATION, BDPT_SLOT, BDPT_STEP, BDPT_VERTEX, CONNECT_ARGS, SUBPATH,
                                 ListingInt, SimdSum, WalkCounter)
from toolkit.core.scene import NO_LIMIT
from toolkit.opencl.work_sizes import checked_size
from toolkit.techniques.base import Technique, pixel_count
from toolkit.techniques.device_memory import DeviceMemory
from toolkit.techniques.kernels import Kernels
from toolkit.techniques.pass_end import LAG
from toolkit.techniques.simd_recorder import SimdRecorder


WITHOUT_COMPACTION = "walk_without_compaction"   # the recorder's counter of the walk as it would be without compaction
RECENT_WALKS = 4   # passes whose walks' lengths say when the next pass's walk ends (BdptEvaluator.walk_steps)


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
    lane_counts: cl.Buffer    # LaneCounts[pool]: the stream's lanes in one walk step (COUNT_SIMD)
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
    counters: cl.Buffer       # int[COUNTER_INTS]: the streams' lengths (a ring), terminated samples (WalkCounter)
    lane_counts: cl.Buffer    # LaneCounts[size]: one connect phase (COUNT_SIMD)
    all_slots: cl.Buffer      # 0 .. size - 1: the slot list of the first regeneration
    record_counts: cl.Buffer  # int[size]: each slot's records in the next connect phase (its count kernel)
    record_firsts: cl.Buffer  # int[size]: where each listed slot's records start (their exclusive scan)
    listed: cl.Buffer         # int[size]: the slots listed for the next connect phase, then regenerated
    block_sums: cl.Buffer     # int2[work-groups of the pool]: the listing's sums per work-group, then their scan
    listing: cl.Buffer        # int[ListingInt.INTS]: what the host reads of a listing (Listing)


@dataclass
class Listing:
    """The terminated samples listed on the device for a connect phase (BdptEvaluator.list_terminated):
    their slots, and the read of what the host needs, queued at walk step `step` and looked at LAG
    steps later: the listed slots (0: too few had terminated), the connect phase's records, the
    streams' lengths as they were and the walk's steps so far (cl/bdpt_walk.h bdpt_list_offsets).
    `waits_for_all`: it lists only once every sample in flight has terminated (the drain's last)."""
    slots: cl.Buffer          # int[pool]: the listed slots, the first `count` of it
    counts: object            # PendingRead of int[ListingInt.INTS]
    step: int
    waits_for_all: bool = False

    def result(self):
        """(slots, listed slots, records, the streams' (eye, light) lengths, the walk's steps)."""
        counts = self.counts.result()
        return (self.slots, int(counts[ListingInt.LISTED]), int(counts[ListingInt.RECORDS]),
                counts[ListingInt.EYE_LENGTH:ListingInt.LIGHT_LENGTH + 1], int(counts[ListingInt.WALK_STEPS]))


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
    steps: int = 0            # walk steps so far
    ring: int = 0             # where the next walk step reads the streams' lengths: pair `ring` of the counters' ring
    appended: int = 0         # subpaths regenerated onto each stream since the last walk step
    started_at: int = 0       # the step of the last regeneration that started samples
    list_at: int = 0          # the step of the next listing
    retry: int = 0            # steps before the next listing after one that listed none (doubles each time)
    listed: Listing = None    # the terminated samples listed for the next connect phase, if any

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


class OwnCounts:
    """The walk steps' arguments for counting their own lanes (BdptEvaluator.own_counts): the step
    log's buffer and, per walking stream, a BdptStep with its row and stamp. One writable record per
    stream, changed in place (program.launch compares its bytes): a render counts thousands of steps."""

    # BdptStep's fields in order (layout.py): a step sets its record with one tuple, ~0.3 us, where
    # five fields one by one took ~2.5 us
    FIELDS = ("ring", "appended", "light", "simd_row", "simd_stamp", "simd_warp_width", "simd_stamps_at")

    def __init__(self, warp_width):
        if BDPT_STEP.dtype.names != self.FIELDS:
            raise RuntimeError(f"OwnCounts.FIELDS is not BdptStep's fields: {BDPT_STEP.dtype.names}")
        self.log, self.rows, self.warp_width = None, {}, warp_width
        self.arrays = [BDPT_STEP.zeros(1) for _ in range(2)]   # eye, light: one record each, changed in place
        self.records = [array[0] for array in self.arrays]       # views of them, the launches' arguments

    def start(self, counts, walking):
        """This step's (log buffer, stamps' place, row, stamp) for each stream in `walking`."""
        self.rows = {stream.is_light: count for stream, count in zip(walking, counts)}
        self.log = counts[0][0]

    def step(self, p, stream):
        """The stream's BdptStep for this step, counting into its row."""
        light = stream.is_light
        _, stamps_at, row, stamp = self.rows[light]
        self.arrays[light][0] = (p.ring, p.appended, int(light), row, stamp, self.warp_width, stamps_at)
        return self.records[light]


@dataclass
class BdptContext:
    """What BDPT's evaluator and its connect phases use of a technique, and nothing more."""
    queue: cl.CommandQueue
    kernels: Kernels          # the technique's program (the walk's and connect phase's kernels) and its launches
    memory: DeviceMemory      # where the pool, the streams and the records are allocated
    recorder: SimdRecorder    # the technique's SIMD counters: the walk's steps count as its iterations


# BDPT's default regeneration threshold (the talk's postponed regeneration): connect the
# terminated samples and start new ones once this share of the samples in flight has terminated.
REGENERATE_FRACTION = 0.6


class BdptPoolTechnique(Technique):
    """A technique whose samples are BDPT samples of a pool (BdptEvaluator): the BDPT techniques,
    which add them into an image, and mlt, whose chains propose them. It builds the walk's kernels
    for the scene and sizes the pool for the device; the subclass makes its
    evaluator with the connect phase it wants (self.bdpt). The walk compacts its streams and lists
    the terminated samples with its own kernels (cl/bdpt_walk.h), not the Compactor's."""
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
        # What the evaluator and the connect phase get of this technique (not the technique itself).
        self.bdpt_context = BdptContext(queue, self.kernels, self.memory, self.recorder)
        self.bdpt = None            # the subclass's BdptEvaluator

    def extra_stats(self):
        return {**super().extra_stats(), **self.bdpt.stats()}


@dataclass
class BdptEvaluator:
    """The walk of BDPT's kernels (launched through `ctx`) and a connect phase: its kernel
    `connect.count_kernel` writes the records of each terminated sample's slot of pass `p`
    (p.pool.record_counts), and `connect(p, count, records)` evaluates the connections of the
    `count` samples listed then (`records` records, starting at p.pool.record_firsts) and returns
    their Connections."""
    ctx: BdptContext           # the kernels, memory and SIMD recorder of the technique that built them
    connect: object            # the connect phase: count_kernel; (PassState, count, records) -> Connections
    pool_size: int             # samples in flight
    regenerate_fraction: float  # connect (and regenerate) once this share of the samples in flight has terminated
    max_vertices: int          # per subpath (MAX_VERTICES)
    last_pass: PassState = None   # kept for inspection (tests, notebooks): the vertex memory of the last samples
    listing_delay: int = 1     # steps after a regeneration to list (grows when a listing succeeds only later)
    walk_steps: list = field(default_factory=list)   # the walks' lengths (steps) of the last RECENT_WALKS passes
    _steps: dict = field(default_factory=dict, repr=False)   # BdptStep records by (ring, appended, stream), made once
    _replays: dict = field(default_factory=dict, repr=False)   # walk_replay's, by (pool size, draining)
    _own: object = field(default=None, repr=False)        # an OwnCounts, made at the first counted step (own_counts)

    def __post_init__(self):
        fraction = self.regenerate_fraction
        if isinstance(fraction, bool) or not isinstance(fraction, numbers.Real) or not 0.0 < fraction <= 1.0:
            raise ValueError(f"regenerate_fraction must be a number in (0, 1], got {fraction!r}")

    def evaluate(self, p, sink):
        """Every sample of the pass's budget, through the pool; `sink.add` gets each connect phase's records."""
        self.regenerate(p, p.pool.all_slots, p.pool.size)        # every slot starts a sample
        while p.in_flight > 0:
            self.walk(p)                                          # one vertex more on every subpath
            if p.listed is None:
                if p.steps >= p.list_at:
                    p.listed = self.list_terminated(p)            # postponed regeneration: list the terminated
            elif p.steps >= p.listed.step + LAG:                  #   samples if enough; their counts, read late:
                slots, count, records = self.listing_read(p)
                if count:
                    sink.add(self.connect(p, count, records))     #   connect them,
                    self.regenerate(p, slots, count)              #   then start new ones in their slots

    def threshold(self, p):
        """Terminated samples that make a connect phase worth it: the share regenerate_fraction of
        the samples in flight (so once every one has terminated, whatever the share). Once the
        budget is spent, regeneration starts nothing: every one (one connect phase, not a tail of
        ever smaller ones, each a listing and a read). The naive connect's idle lanes stay: on
        cornell_box 64x64 its connect phase keeps 24% of its lanes busy (21% with the tail)."""
        if p.next_id >= p.budget:
            return p.in_flight
        return max(1, math.ceil(self.regenerate_fraction * p.in_flight))

    # --- the stages of a pass, one kernel each ---------------------------------------------

    def start_pass(self, camera, seed, sample_base, budget, sampler_args=None, vector_stride=0):
        """The pass's state for `budget` samples; every slot of the pool starts terminated
        (nothing in flight). Kernels built with a sampler that reads stored primary-sample
        vectors (cl/mlt_proposals.h) take them as `sampler_args` (by parameter name), with their stride `vector_stride`
        (BdptPass.chains); plain BDPT has neither."""
        ctx = self.ctx
        pool = self.sample_pool(min(self.pool_size, budget))
        args = BDPT_PASS.record(seed=seed, sample_base=sample_base, pool=pool.size, capacity=pool.capacity,
                                chains=vector_stride, pixels=pixel_count(camera))
        # the streams' lengths: 0 here and on the device; nothing terminated, no walk step yet
        cl.enqueue_fill_buffer(ctx.queue, pool.counters, np.int32(0), 0, 4 * WalkCounter.COUNTER_INTS)
        pool.eye.length = pool.light.length = 0
        # every slot counts as in flight until the first regeneration (of them all) starts them
        self.last_pass = PassState(pool, camera, args, budget, dict(sampler_args or {}), in_flight=pool.size)
        return self.last_pass

    def sample_pool(self, size):
        """The streams, the vertex memory (tens of MB) and the per-slot arrays, made once per pool size."""
        ctx, mem = self.ctx, self.ctx.memory
        context, capacity = ctx.queue.context, mem.stream_capacity(size)
        vertex_bytes = BDPT_VERTEX.dtype.itemsize * size * self.max_vertices

        def stream(is_light):
            return SubpathStream(is_light, mem.soa_buffer(SUBPATH, size), mem.soa_buffer(SUBPATH, size),
                                 cl.Buffer(context, cl.mem_flags.READ_WRITE, vertex_bytes), mem.lane_counts_buffer(size))
        return mem.reused(("pool", size), lambda: SamplePool(
            size, capacity, stream(0), stream(1),
            slots=cl.Buffer(context, cl.mem_flags.READ_WRITE, BDPT_SLOT.dtype.itemsize * mem.padded(size)),
            counters=mem.int_buffer(WalkCounter.COUNTER_INTS), lane_counts=mem.lane_counts_buffer(size),
            all_slots=cl.Buffer(context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                                hostbuf=np.arange(size, dtype=np.int32)),
            record_counts=mem.int_buffer(size), record_firsts=mem.int_buffer(size), listed=mem.int_buffer(size),
            block_sums=mem.int_buffer(2 * (mem.padded(size) // mem.local_size)), listing=mem.int_buffer(ListingInt.INTS)))

    def regenerate(self, p, slots, count):
        """bdpt_regenerate: the `count` slots listed in `slots` start the next samples of the
        budget (the rest go idle); the new subpaths join the end of the streams, after the lengths
        on the device, and the next walk step adds them to those lengths (p.appended). The host
        knows only a bound on the lengths, which grows by the new subpaths."""
        ctx, pool = self.ctx, p.pool
        fresh = min(count, p.budget - p.next_id)
        if count:
            for stream in (pool.eye, pool.light):   # the eye launch also starts the slots
                r = BDPT_REGENERATION.record(count=count, fresh=fresh, first_id=p.next_id, ring=p.ring,
                                             appended=p.appended, light=int(stream.is_light))
                ctx.kernels.launch("bdpt_regenerate", count, **ctx.kernels.scene_args(), cam=p.camera,
                                   pass_args=p.args, r=r, slot_list=slots, counters=pool.counters,
                                   stream=stream.current, vertices=stream.vertices, slots=pool.slots,
                                   **p.sampler_args)
        for stream in (p.pool.eye, p.pool.light):    # a stream holds at most one subpath per slot
            stream.length = min(stream.length + fresh, p.pool.size)
        p.appended += fresh
        p.next_id += fresh
        p.in_flight += fresh - count
        p.retry = 0
        if fresh:
            p.started_at = p.steps
        p.list_at = self.walk_end(p) if self.waits_for_all(p) else p.steps + self.listing_delay
        if ctx.recorder.on and fresh:
            ctx.recorder.stream_step("generate", fresh)

    def walk(self, p):
        """One random-walk step: bdpt_extend extends the eye stream, then the light stream (each
        compacted at once), over bounds on their lengths that the host knows (the kernel reads the
        lengths on the device: pair p.ring of the counters' ring, plus the subpaths regenerated
        since). Both launch while either stream walks, an empty one as one work-group, because each
        launch also clears its stream's count two steps ahead in the ring. Nothing to launch while
        both are empty (the terminated samples wait for their connect phase)."""
        ctx, pool = self.ctx, p.pool
        p.steps += 1
        if not (pool.eye.length or pool.light.length):
            return
        k, mem = ctx.kernels, ctx.memory
        counted = self.own_counts(p)     # the rows of the step log the launches add their lanes to, if any
        for stream in (pool.eye, pool.light):
            if counted and stream.length:
                step, log = counted.step(p, stream), counted.log
            else:
                step, log = self.walk_step_record(p, stream), pool.counters   # counts nothing (any buffer)
            k.launch("bdpt_extend", mem.padded(stream.length), **k.scene_args(), pass_args=p.args,
                     walk_step=step, stream=stream.current, next_stream=stream.spare, counters=pool.counters,
                     vertices=stream.vertices, slots=pool.slots, lane_counts=stream.lane_counts, simd_log=log,
                     **p.sampler_args)
        self.count_walk_step(p, counted=counted is not None)
        pool.eye.advance()
        pool.light.advance()
        p.ring, p.appended = (p.ring + 1) % 3, 0

    def lengths_known(self, p, lengths):
        """The streams can hold no more subpaths than a read of their (eye, light) lengths says (they
        only shrink until the next regeneration): later steps launch over that many."""
        p.pool.eye.length = min(p.pool.eye.length, int(lengths[0]))
        p.pool.light.length = min(p.pool.light.length, int(lengths[1]))

    def waits_for_all(self, p):
        """Whether the next listing lists only once every sample in flight has terminated: once the
        budget is spent (nothing will be regenerated), the threshold is all of them."""
        return p.next_id >= p.budget

    def every_subpath_ended(self, p):
        """The walk step by which every subpath has ended: one has at most MAX_VERTICES vertices,
        the first made when its sample started."""
        return p.started_at + self.max_vertices - 1

    def walk_end(self, p):
        """The step by which the walk has likely ended: as long after the pass's start as the longest
        of the last passes' walks, and no later than every subpath's end."""
        return min(self.every_subpath_ended(p), max(self.walk_steps, default=self.every_subpath_ended(p)))

    def listing_read(self, p):
        """The listing's read, looked at: (slots, listed slots, records). The walk's counters read
        with it bound the streams' lengths. Listed: the next listing follows the next regeneration
        by as many steps more as this one came after its planned step (a retry at once lists on the
        next step), so the delay grows until listings succeed when planned; the drain's last listing
        keeps the walk's length for the next passes. None listed (too few had terminated): the
        drain's last lists again once every subpath has ended; another lists again at once, then
        after 1, 2, 4, ... steps."""
        slots, count, records, lengths, walked = p.listed.result()
        if count and p.listed.waits_for_all:
            self.walk_steps = (self.walk_steps + [walked])[-RECENT_WALKS:]
        elif count:                   # listed later than planned (a retry): list that much later next time
            self.listing_delay = max(1, self.listing_delay + p.listed.step - p.list_at)
        elif p.listed.waits_for_all and p.steps < self.every_subpath_ended(p):
            p.list_at = self.every_subpath_ended(p)             # sure to list them all then
        else:
            p.list_at, p.retry = p.steps + p.retry, max(1, 2 * p.retry)
        p.listed = None
        self.lengths_known(p, lengths)
        return slots, count, records

    def list_terminated(self, p):
        """The terminated samples, listed on the device for the next connect phase, if there are
        enough of them (threshold): the connect phase's record counts (its count kernel, while the
        samples are SLOT_TERMINATED), then bdpt_mark_terminated (they become SLOT_CONNECTING, if
        enough), bdpt_list_offsets and bdpt_list_terminated (the scan of their records, the list of
        their slots: cl/bdpt_walk.h). What the host needs goes to one small buffer, read behind
        the next steps (a Listing)."""
        ctx, pool = self.ctx, p.pool
        k, size = ctx.kernels, pool.size
        k.launch(self.connect.count_kernel, size, pool=k.int32(size), slots=pool.slots, counts=pool.record_counts)
        k.launch("bdpt_mark_terminated", size, pool=k.int32(size), threshold=np.int32(self.threshold(p)),
                 counters=pool.counters, slots=pool.slots, counts=pool.record_counts, block_sums=pool.block_sums)
        k.launch("bdpt_list_offsets", 1, blocks=k.int32(ctx.memory.padded(size) // k.local_size), ring=k.int32(p.ring),
                 counters=pool.counters, block_sums=pool.block_sums, listing=pool.listing)
        k.launch("bdpt_list_terminated", size, pool=k.int32(size), slots=pool.slots, counts=pool.record_counts,
                 block_starts=pool.block_sums, firsts=pool.record_firsts, listed_slots=pool.listed)
        return Listing(pool.listed, ctx.memory.read_later(pool.listing, (np.int32, ListingInt.INTS)), p.steps,
                       self.waits_for_all(p))

    # --- measuring and inspecting ------------------------------------------------------------

    def walk_step_record(self, p, stream):
        """The BdptStep of a launch that counts nothing itself (simd_row -1): one read-only record per
        (ring, appended, stream), made once."""
        key = (p.ring, p.appended, stream.is_light)
        step = self._steps.get(key)
        if step is None:
            step = self._steps[key] = BDPT_STEP.record(ring=p.ring, appended=p.appended, light=int(stream.is_light),
                                                       simd_row=-1, simd_stamp=0, simd_warp_width=1,
                                                       simd_stamps_at=0)
        return step

    def own_counts(self, p):
        """Where this step's launches add their own lanes to the SIMD counters' step log (counting,
        not per step, and W dividing the work-group: cl/simd_counters.h simd_count_group), an
        OwnCounts with each walking stream's row and stamp, in launch order; else None (the step is
        counted by count_walk_step's launch, or not at all)."""
        ctx, pool = self.ctx, p.pool
        recorder = ctx.recorder
        if not recorder.on or ctx.kernels.local_size % recorder.warp_width:
            return None
        walking = [stream for stream in (pool.eye, pool.light) if stream.length]
        counts = recorder.counted_by_kernels(self.walk_replay(p), len(walking), pool.size)
        if not counts:          # per-step mode (None), or no stream walking
            return None
        if self._own is None:
            self._own = OwnCounts(recorder.warp_width)
        self._own.start(counts, walking)
        return self._own

    def walk_replay(self, p):
        """The replay of a walk step's row (SimdRecorder), one per pool size and drain (kept): a
        stream's lanes are the first of the length the step extended, its pool warps those holding
        the slots of the subpaths it extended (the walk as it would be without compaction)."""
        pool, draining = p.pool.size, p.next_id == p.budget
        key = (pool, draining)
        if key not in self._replays:
            self._replays[key] = self._walk_replay(pool, draining)
        return self._replays[key]

    @staticmethod
    def _walk_replay(pool, draining):
        def replay(recorder, sums):
            if sums.lanes is None:
                return recorder.walk_row(sums.sums, pool, draining, WITHOUT_COMPACTION)
            length = sums[SimdSum.LANES]
            if length == 0:
                return      # a stream the device had found empty
            recorder.count_now("walk", length, numbered=True, capacity=pool, draining=draining)
            recorder.simd_counter().add_stream_step("compact", length)
            recorder.warp_loops(recorder.traversal_counter(), "closest", sums, "closest_steps")
            # without compaction each path keeps its slot's lane
            recorder.slot_warps(recorder.counter(WITHOUT_COMPACTION), "walk", sums, pool)
        return replay

    def count_walk_step(self, p, counted=False):
        """SIMD counters of one walk step (a no-op unless count_simd), summed on the device: by the
        step's own launches where they counted (`counted`: own_counts), which leaves only a
        reference recorder (check_against_host) to give the lanes to; else both streams with one
        counting launch. A stream's lanes are the first of the length the step extended
        (counters), its slots those of the subpaths it extended (for the walk without compaction)."""
        ctx = self.ctx
        if not ctx.recorder.on or (counted and ctx.recorder.reference is None):
            return
        pool, replay = p.pool.size, self.walk_replay(p)
        slot_offset = SUBPATH.soa_offset("slot", p.pool.capacity) // 4
        steps = [dict(lanes=stream.lane_counts, stride=4, bound=stream.length, length_at=p.pool.counters,
                      length_index=int(length), slot_of=stream.current, slot_offset=slot_offset, pool=pool)
                 for stream, length in ((p.pool.eye, WalkCounter.STEP_EYE_LENGTH),
                                        (p.pool.light, WalkCounter.STEP_LIGHT_LENGTH)) if stream.length]
        if counted:             # by bdpt_extend, into rows queued before it: the lanes go only to the reference
            for step in steps:
                ctx.recorder.reference.lanes(replay, **step)
        elif len(steps) == 2:   # both streams with one launch
            ctx.recorder.lanes_two((replay, steps[0]), (replay, steps[1]))
        elif steps:
            ctx.recorder.lanes(replay, **steps[0])

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


def connect_args(p, firsts, values, pixels, lane_counts):
    """CONNECT_PARAMS by name (layout.py CONNECT_ARGS, in its order): what both connect kernels
    read (the scan of the slots' record counts, the pool, its vertices) and write (the records)."""
    given = dict(firsts=firsts, slots=p.pool.slots, eye_vertices=p.pool.eye.vertices,
                 light_vertices=p.pool.light.vertices, record_value=values, record_pixel=pixels,
                 lane_counts=lane_counts)
    return {name: given[name] for name, _ in CONNECT_ARGS}


def record_buffers(ctx, n, *more):
    """Device memory for n records (float4 values, int pixels, and `more(capacity)` buffers), reused
    by the next connect phases. Made with room for half as many again (in powers of two), so that
    the later connect phases of a render, about the size of its first, rarely outgrow it: a new
    buffer costs the host at its first launch (a device allocates it then). Outgrown, it is replaced."""
    held = ctx.memory.reused("records", dict)     # {"capacity": records, "buffers": (values, pixels, *more)}
    if held.get("capacity", 0) < n:
        capacity = 1 << max(12, (n + n // 2 - 1).bit_length())
        held.clear()                               # the old buffers go (the queued commands still hold them)
        held.update(capacity=capacity, buffers=(
            cl.Buffer(ctx.queue.context, cl.mem_flags.READ_WRITE, 16 * capacity), ctx.memory.int_buffer(capacity),
            *(make(capacity) for make in more)))
    return held["buffers"]


def per_pixel_sums(values, pixels, npix):
    """(npix, 3) float64 sums of RGB `values` by pixel index."""
    return np.stack([np.bincount(pixels, values[:, k], minlength=npix) for k in range(3)], axis=1)
