"""Path tracing on a compacted stream with regeneration at its end (the talk's
"Stream Compaction + Regeneration", with single-pass "immediate" compaction).

Kernel: cl/pt_compact_regen.cl. The stream has a fixed size; one iteration:
    extend      - all paths in the stream take one vertex (every lane busy): trace finds each
                  ray's closest hit, shade adds emission, prepares the shadow ray, samples the
                  BSDF (two kernels: a wavefront path tracer, Laine et al. 2013);
    compact     - ended paths leave, survivors are packed at the start of the stream;
    regenerate  - new samples fill the end of the stream: consecutive pixels, side by side
                  (queued as the next step's first work: the trace kernel's work-items past the
                  survivors start their sample, then trace it, one launch for both; the same
                  launch first traces the last step's queued shadow rays).
With compaction="immediate" the compaction is fused into the shade kernel (one scan per
work-group in local memory, one atomic per group); "multipass" extends in place
(extend_in_place_trace and _shade, whose per-slot code pt_inplace_regen shares), then labels, scans and gathers.
The counts stay on the device: each step's PtStep record (toolkit/core/layout.py) holds the
stream's length, what compaction counted and the next sample to start; every kernel is launched
over the whole stream and a work-item past the count returns at once. The host never waits for a
count to launch the next step: it reads a step's record now and then, behind the device, to
learn that the pass is over (pass_end.py); in the final drain such a read also bounds the
launches (the stream only shrinks). The SIMD counters too are summed on the device, each step's
row read back with the others (techniques/simd_recorder.py).
Option `stream_size`: the paths in the stream (default: the device's, toolkit/opencl/work_sizes.py:
32,768 on a CPU).
"""
from dataclasses import dataclass

import pyopencl as cl

from toolkit.opencl.compaction import Compactor
from toolkit.core.layout import HIT_RECORD, PATH_STATE, PT_PASS, PT_STEP, SHADOW_RAY
from toolkit.opencl.work_sizes import checked_size
from toolkit.techniques.base import Technique, pixel_count
from toolkit.techniques.pass_end import PassEnd
from toolkit.techniques.simd_recorder import StepPairs


@dataclass
class StreamBuffers:
    """pt_compact_regen's device memory: made once per stream size, reused by every pass."""
    stream: cl.Buffer        # PathState x capacity, a structure of arrays: the paths in flight, packed at its start
    next_stream: cl.Buffer   # the same: each step writes its survivors here, packed; then the two swap
    hits: cl.Buffer          # HitRecord x capacity: each path's closest hit, from trace to shade
    shadow_rays: cl.Buffer   # ShadowRay x capacity: the shadow rays a step queued, packed (immediate compaction)
    lane_counts_by_turn: tuple   # LaneCounts per path, one buffer per turn: what it did in an extension step (COUNT_SIMD)
    alive: cl.Buffer         # int per path: 1 where the stream holds a live path (multi-pass compaction's flags)
    counts: cl.Buffer        # PtStep: this step's counts (its length, survivors, shadow rays, next sample)
    last_counts: cl.Buffer   # PtStep: the last step's, from which regeneration starts this step's
    indices: cl.Buffer       # int per path: the survivors' indices from the scan (multi-pass; None: immediate)
    radiance: cl.Buffer = None   # float4 per sample of the pass (DeviceMemory.output_buffer): set by each pass
    turn: int = 0            # which of the two buffers of each pair is the stream (flips with swap)

    @property
    def lane_counts(self):
        """This step's LaneCounts: the two steps before the SIMD counters sum them (StepPairs) write
        to different buffers (one buffer for both turns when nothing counts)."""
        return self.lane_counts_by_turn[self.turn]

    def swap(self):
        """After a step: the survivors, packed into next_stream, are the stream, and its counts the last step's."""
        self.stream, self.next_stream = self.next_stream, self.stream
        self.counts, self.last_counts = self.last_counts, self.counts
        self.turn ^= 1


class PtCompactRegen(Technique):
    name = "pt_compact_regen"
    family = "pt"
    source = "pt_compact_regen.cl"

    reads_every = 8      # steps between the host's looks at the device's counts (counters off: pass_end.py)

    def __init__(self, *args, compaction="immediate", stream_size=None, **kwargs):
        checked_size("stream_size", stream_size)     # its range now, before the build; the device's memory after
        super().__init__(*args, **kwargs)
        self.stream_size = self.size_in_flight("stream_size", stream_size)   # paths in the stream; None: the device's
        if compaction not in ("immediate", "multipass"):
            raise ValueError(f"compaction must be 'immediate' or 'multipass', not {compaction!r}")
        self.compaction = compaction
        # immediate: shadow rays go to a queue, traced (and counted) in the next step's trace kernel
        self.shadow_queue = compaction == "immediate"
        multipass = compaction == "multipass"
        self.compactor = Compactor(self.queue, self.local_size, self.sources.toolkit_only()) if multipass else None

    def stream_buffers(self, size):
        """The device memory of a stream of `size` paths (run_pass makes it once per stream size)."""
        m = self.memory
        return StreamBuffers(
            stream=m.soa_buffer(PATH_STATE, size), next_stream=m.soa_buffer(PATH_STATE, size),
            hits=m.soa_buffer(HIT_RECORD, size),
            shadow_rays=m.soa_buffer(SHADOW_RAY, size),
            lane_counts_by_turn=self.by_turn(lambda: m.lane_counts_buffer(size)), alive=m.int_buffer(size),
            counts=m.record_buffer(PT_STEP), last_counts=m.record_buffer(PT_STEP), indices=self.compacted_indices(size))

    def run_pass(self, film, camera, seed, sample_base, spp):
        budget = pixel_count(camera) * spp
        size = min(self.stream_size, budget)
        mem = self.memory.reused(("streams", size), lambda: self.stream_buffers(size))
        mem.radiance = self.memory.output_buffer(budget)
        self.memory.fill_ints(mem.last_counts, 0)     # an empty stream; the pass's first sample comes next
        pass_args = PT_PASS.record(seed=seed, sample_base=sample_base, budget=budget,
                                   capacity=self.memory.stream_capacity(size))
        # The pass is over once the stream is empty and every sample has started.
        end = PassEnd(self.memory, PT_STEP.dtype, lambda counts: counts["survivors"] == 0
                      and counts["next_sample"] == budget, every=self.reads_every, at_least=-(-budget // size))
        paths = size    # stream entries each launch covers: the whole stream, until a read bounds its length
        counting = PassCount(size, budget, self.shadow_queue, StepPairs(self.recorder)) if self.count_simd else None
        while True:
            # Regenerate the end of the stream with the next samples of the budget, extend every path by
            # one vertex (trace, then shade), and compact the survivors into next_stream.
            # The shadow rays the step queued, a packed stream of their own, are traced by the next
            # step's first launch.
            self.regenerate_and_extend(camera, pass_args, size, paths, mem)
            if counting:
                self.count_step(counting, mem, paths, size, budget)
            mem.swap()
            if end.reached(mem.last_counts):
                # A step some time ago left nothing to do: the steps since did nothing but trace its
                # shadow rays (PassEnd says so at least one step after the step it read, so the
                # step after it, which traced them, was queued).
                break
            paths = self.paths_at_most(end.latest, size, budget)   # from a step's counts, some steps old
        if counting:
            counting.pairs.close()
        self.collect(film, mem.radiance, budget)

    @staticmethod
    def paths_at_most(counts, size, budget):
        """The most paths the stream can hold from the next step on, from a step's `counts` read
        some steps ago: once every sample of the budget has started, the stream only shrinks, so
        that step's survivors bound every later step's length; before, the whole stream (`size`)."""
        if counts is None or int(counts["next_sample"]) < budget:
            return size
        return max(1, int(counts["survivors"]))    # at least one: a launch (and a scan) of none is no launch

    def compacted_indices(self, size):
        """Multi-pass compaction's output (the survivors' indices) and the compactor's scratch
        memory, made with the streams: no iteration allocates. None for immediate compaction."""
        if self.compactor is None:
            return None
        self.compactor.reserve(size)
        return self.memory.int_buffer(size)

    def regenerate_and_extend(self, camera, pass_args, size, paths, mem):
        """Regenerate: entries past the last step's survivors start the next samples of the budget,
        as many as fit in the stream's `size`; the step's record counts them (the device decides
        how many). Extend: the paths of mem.stream take one vertex (counts.length of the first
        `paths` entries, a bound of the stream's length: paths_at_most); the survivors are packed at
        the start of mem.next_stream, and counted in counts.survivors.
        Immediate compaction regenerates inside the trace kernel, which also traces the last step's
        shadow rays: a step is two launches, and inside a render each launch costs the host tens
        of microseconds (results/issue48_launch_path.md)."""
        k = self.kernels
        regeneration = dict(cam=camera, pass_args=pass_args, stream_size=k.int32(size),
                            last_counts=mem.last_counts, counts=mem.counts, stream=mem.stream)
        if self.compaction == "immediate":
            # A kernel object per turn of the swapping streams: each keeps its arguments set (program.kernel).
            trace, shade = (k.kernel(name, copy=mem.turn) for name in ("pt_compact_regen_trace", "pt_compact_regen_shade"))
            k.launch(trace, paths, **k.scene_args(), **regeneration, hits=mem.hits,
                     shadow_rays=mem.shadow_rays, radiance=mem.radiance, lane_counts=mem.lane_counts)
            k.launch(shade, paths, **k.scene_args(), pass_args=pass_args,
                     counts=mem.counts, stream=mem.stream, hits=mem.hits, next_stream=mem.next_stream,
                     shadow_rays=mem.shadow_rays, radiance=mem.radiance, lane_counts=mem.lane_counts)
            return
        k.launch("pt_compact_regen_generate", paths, **regeneration, alive=mem.alive)
        # Multi-pass: the entries that hold a live path (alive: set by gather and regeneration) take the step in place.
        self.extend_in_place(pass_args, paths, mem.stream, mem.alive, mem.hits, mem.radiance, mem.lane_counts)
        indices, survivors = self.compactor.compact_on_device(mem.alive, paths, out=mem.indices)
        k.launch("pt_compact_regen_gather", paths, pass_args=pass_args, survivors=survivors, indices=indices,
                 stream=mem.stream, next_stream=mem.next_stream, counts=mem.counts, alive=mem.alive)

    # --- SIMD counting, summed on the device (simd_recorder.py); no-op unless count_simd ----------

    def count_step(self, counting, mem, paths, size, budget):
        """The SIMD counters of the step just queued, summed on the device with the next step's
        (StepPairs: this step's lanes and counts are in this turn's buffers): the `paths` lanes its
        launches covered (past the stream's length a lane has no work, but its .shadow_steps counts
        a ray of the last step's shadow queue: cl/pt_compact_regen.cl) and its counts (PtStep,
        copied into the row)."""
        counting.pairs.lanes(counting.extended, lanes=mem.lane_counts, stride=4, bound=paths,
                             watch=mem.counts, watch_count=len(PT_STEP.dtype.names))


class PassCount:
    """The counters of one pass's steps, replayed in order (by each recorder that counts them) from
    each step's sums and its counts (PtStep, watched): the last step's shadow queue (traced by
    this step's first launch), then regeneration, extension and compaction. The first step that
    finds the stream empty ends the pass (budget spent and drained; it traced the last shadow
    rays): nothing after it is counted (the host went on queueing steps until it learned so:
    pass_end.py)."""

    def __init__(self, size, budget, shadow_queue, pairs):
        self.size, self.budget, self.shadow_queue = size, budget, shadow_queue
        self.pairs = pairs          # the pass's steps, counted two to a launch
        self.ended = set()          # the recorders that have counted the pass's end
        self.queued = {}            # by recorder: the shadow rays the last step it counted queued

    def extended(self, recorder, sums):
        if recorder in self.ended:
            return
        counts = {name: sums.watched(k) for k, name in enumerate(PT_STEP.dtype.names)}
        queued = self.queued.get(recorder, 0)
        if self.shadow_queue and queued:   # the packed shadow queue: every lane busy,
            recorder.simd_counter().add_stream_step("shadow", queued)   # traversal loops per warp
            recorder.warp_loops(recorder.traversal_counter(), "shadow", sums, "shadow_steps")
        self.queued[recorder] = counts["shadow_rays"]
        length, started = counts["length"], counts["started"]
        if length == 0:
            self.ended.add(recorder)
            return
        draining = counts["next_sample"] == self.budget   # every sample of the budget has started (the final drain)
        if started > 0:   # regeneration fills `started` consecutive stream entries: every lane busy
            recorder.count_now("generate", started, before=True, capacity=self.size, draining=draining)
        recorder.extension_step(sums, capacity=self.size, draining=draining, shadow_queue=self.shadow_queue)
        recorder.simd_counter().add_stream_step("compact", length)
