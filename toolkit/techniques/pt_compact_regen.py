"""Path tracing on a compacted stream with regeneration at its end (the talk's
"Stream Compaction + Regeneration", with single-pass "immediate" compaction).

Kernel: cl/pt_compact_regen.cl. The stream has a fixed size; one iteration:
    extend      - all paths in the stream take one vertex (every lane busy): trace finds each
                  ray's closest hit, shade adds emission, prepares the shadow ray, samples the
                  BSDF (two kernels: a wavefront path tracer, Laine et al. 2013);
    compact     - ended paths leave, survivors are packed at the start of the stream;
    regenerate  - new samples fill the end of the stream: consecutive pixels, side by side.
With compaction="immediate" the compaction is fused into the shade kernel (one scan per
work-group in local memory, one atomic per group); "multipass" extends in place
(extend_in_place_trace and _shade, shared with pt_inplace_regen), then labels, scans and gathers.
Option `stream_size`: the paths in the stream (default: the device's, toolkit/opencl/work_sizes.py:
32,768 on a CPU).
"""
from dataclasses import dataclass

import numpy as np
import pyopencl as cl

from toolkit.opencl.compaction import Compactor
from toolkit.core.layout import HIT_RECORD, PATH_STATE, PT_PASS, PT_REGENERATION, SHADOW_RAY, StreamCounter
from toolkit.opencl.work_sizes import checked_size
from toolkit.techniques.base import Technique, pixel_count


@dataclass
class StreamBuffers:
    """pt_compact_regen's device memory: made once per stream size, reused by every pass."""
    stream: cl.Buffer        # PathState x capacity, a structure of arrays: the paths in flight, packed at its start
    next_stream: cl.Buffer   # the same: each step writes its survivors here, packed; then the two swap
    hits: cl.Buffer          # HitRecord x capacity: each path's closest hit, from trace to shade
    shadow_rays: cl.Buffer   # ShadowRay x capacity: the shadow rays a step queued, packed (immediate compaction)
    lane_counts: cl.Buffer   # LaneCounts per path: what it did in an extension step (COUNT_SIMD)
    alive: cl.Buffer         # int per path: 1 where it survived the step (multi-pass compaction's flags)
    shadow_steps: cl.Buffer  # int per queued shadow ray: the BVH nodes it visited (COUNT_SIMD)
    counters: cl.Buffer      # int per StreamCounter: the survivors and queued shadow rays of a step (immediate)
    indices: cl.Buffer       # int per path: the survivors' indices from the scan (multi-pass; None: immediate)
    radiance: cl.Buffer = None   # float4 per sample of the pass (DeviceMemory.output_buffer): set by each pass

    def swap(self):
        """After a step: the survivors, packed into next_stream, are the stream."""
        self.stream, self.next_stream = self.next_stream, self.stream


class PtCompactRegen(Technique):
    name = "pt_compact_regen"
    family = "pt"
    source = "pt_compact_regen.cl"

    def __init__(self, *args, compaction="immediate", stream_size=None, **kwargs):
        checked_size("stream_size", stream_size)     # its range now, before the build; the device's memory after
        super().__init__(*args, **kwargs)
        self.stream_size = self.size_in_flight("stream_size", stream_size)   # paths in the stream; None: the device's
        if compaction not in ("immediate", "multipass"):
            raise ValueError(f"compaction must be 'immediate' or 'multipass', not {compaction!r}")
        self.compaction = compaction
        # immediate: shadow rays go to a queue traced (and counted) by a kernel of their own
        self.shadow_queue = compaction == "immediate"
        multipass = compaction == "multipass"
        self.compactor = Compactor(self.queue, self.local_size, self.sources.toolkit_only()) if multipass else None

    def stream_buffers(self, size):
        """The device memory of a stream of `size` paths (run_pass makes it once per stream size)."""
        m = self.memory
        return StreamBuffers(
            stream=m.soa_buffer(PATH_STATE, size), next_stream=m.soa_buffer(PATH_STATE, size),
            hits=m.soa_buffer(HIT_RECORD, size),
            shadow_rays=m.soa_buffer(SHADOW_RAY, size), lane_counts=m.lane_counts_buffer(size),
            alive=m.int_buffer(size), shadow_steps=m.int_buffer(size),
            counters=m.int_buffer(len(StreamCounter)), indices=self.compacted_indices(size))

    def run_pass(self, film, camera, seed, sample_base, spp):
        budget = pixel_count(camera) * spp
        size = min(self.stream_size, budget)
        mem = self.memory.reused(("streams", size), lambda: self.stream_buffers(size))
        mem.radiance = self.memory.output_buffer(budget)
        pass_args = PT_PASS.record(seed=seed, sample_base=sample_base, budget=budget,
                                   capacity=self.memory.stream_capacity(size))
        length, next_id = 0, 0
        while True:
            # Regenerate: fill the end of the stream with the next samples of the budget.
            count = min(size - length, budget - next_id)
            if count > 0:
                self.kernels.launch("pt_compact_regen_generate", count, cam=camera, pass_args=pass_args,
                                    r=PT_REGENERATION.record(count=count, first_id=next_id, base=length),
                                    stream=mem.stream)
                length += count
                next_id += count
                self.count_generate(count, size, draining=next_id == budget)
            if length == 0:
                break   # budget spent and the stream has drained
            # Extend every path by one vertex (trace, then shade), then compact the survivors into next_stream.
            survivors, queued = self.extend_and_compact(pass_args, length, mem)
            self.count_extend_and_compact(mem.lane_counts, length, size, draining=next_id == budget)
            # Trace the queued shadow rays: a packed stream of its own.
            if queued:
                self.kernels.launch("pt_compact_regen_shadow", queued, **self.kernels.scene_args(),
                                    pass_args=pass_args, queued=np.int32(queued), shadow_rays=mem.shadow_rays,
                                    radiance=mem.radiance, shadow_steps=mem.shadow_steps)
                self.count_shadow(mem.shadow_steps, queued)
            mem.swap()
            length = survivors
        self.collect(film, mem.radiance, budget)

    def compacted_indices(self, size):
        """Multi-pass compaction's output (the survivors' indices) and the compactor's scratch
        memory, made with the streams: no iteration allocates. None for immediate compaction."""
        if self.compactor is None:
            return None
        self.compactor.reserve(size)
        return self.memory.int_buffer(size)

    def extend_and_compact(self, pass_args, length, mem):
        """Extend the `length` paths of mem.stream; returns (the survivors, now packed at the start
        of mem.next_stream; the queued shadow rays)."""
        k = self.kernels
        if self.compaction == "immediate":
            k.launch("pt_compact_regen_trace", length, **k.scene_args(), pass_args=pass_args,
                     stream_length=np.int32(length), stream=mem.stream, hits=mem.hits, lane_counts=mem.lane_counts)
            cl.enqueue_fill_buffer(self.queue, mem.counters, np.int32(0), 0, 4 * len(StreamCounter))
            k.launch("pt_compact_regen_shade", length, **k.scene_args(), pass_args=pass_args,
                     stream_length=np.int32(length), stream=mem.stream, hits=mem.hits, next_stream=mem.next_stream,
                     shadow_rays=mem.shadow_rays, counters=mem.counters, radiance=mem.radiance,
                     lane_counts=mem.lane_counts)
            lengths = self.memory.read_ints(mem.counters, len(StreamCounter))
            return int(lengths[StreamCounter.PATHS]), int(lengths[StreamCounter.SHADOW_RAYS])
        cl.enqueue_fill_buffer(self.queue, mem.alive, np.int32(1), 0, 4 * length)   # every path in the stream is live
        self.extend_in_place(pass_args, length, mem.stream, mem.alive, mem.hits, mem.radiance, mem.lane_counts)
        indices, survivors = self.compactor.compact_indices(mem.alive, length, method="multipass", out=mem.indices)
        if survivors:
            k.launch("pt_compact_regen_gather", survivors, pass_args=pass_args, count=np.int32(survivors),
                     indices=indices, stream=mem.stream, next_stream=mem.next_stream)
        return survivors, 0

    # --- SIMD counting: one hook per stage, no-ops unless count_simd ----------------------

    def count_generate(self, count, size, draining):
        """Regeneration fills `count` consecutive stream entries: every lane busy. Numbered as the
        extension step that follows it; `draining`: it started the budget's last samples."""
        if self.count_simd:
            self.recorder.before_step("generate", count, capacity=size, draining=draining)

    def count_extend_and_compact(self, lane_counts, length, size, draining):
        """The extension step over the `length` paths of the stream, and their compaction;
        `draining`: every sample of the budget has started (the final drain)."""
        if self.count_simd:
            self.recorder.extension_step(self.memory.read_lane_counts(lane_counts, length), capacity=size,
                                         draining=draining, shadow_queue=self.shadow_queue)
            self.recorder.simd.add_stream_step("compact", length)

    def count_shadow(self, shadow_steps, queued):
        """The packed queue of `queued` shadow rays: every lane busy, traversal loops per warp."""
        if self.count_simd:
            self.recorder.simd.add_stream_step("shadow", queued)
            self.recorder.traversal.add_warp_loops("shadow", self.memory.read_ints(shadow_steps, queued))
