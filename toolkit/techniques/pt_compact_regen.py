"""Path tracing on a compacted stream with regeneration at its end (the talk's
"Stream Compaction + Regeneration", with single-pass "immediate" compaction).

Kernel: cl/pt_compact_regen.cl. The stream has a fixed size; one iteration:
    extend      - all paths in the stream trace one vertex (every lane busy);
    compact     - ended paths leave, survivors are packed at the start of the stream;
    regenerate  - new samples fill the end of the stream: consecutive pixels, side by side.
With compaction="immediate" the compaction is fused into the extend kernel (one scan per
work-group in local memory, one atomic per group); "multipass" labels, scans and gathers.
Option `stream_size`: the paths in the stream (default: the device's, toolkit/opencl/work_sizes.py:
32,768 on a CPU).
"""
import numpy as np
import pyopencl as cl

from toolkit.opencl.compaction import Compactor
from toolkit.core.layout import PATH_STATE, SHADOW_RAY, StreamCounter
from toolkit.opencl.work_sizes import checked_size
from toolkit.techniques.base import Technique


class PtCompactRegen(Technique):
    name = "pt_compact_regen"
    family = "pt"
    source = "pt_compact_regen.cl"
    stream_size = None   # paths in the stream; None: the device's (toolkit/opencl/work_sizes.py)

    def __init__(self, *args, compaction="immediate", stream_size=None, **kwargs):
        checked_size("stream_size", stream_size)     # its range now, before the build; the device's memory after
        super().__init__(*args, **kwargs)
        self.stream_size = self.in_flight("stream_size", stream_size)
        if compaction not in ("immediate", "multipass"):
            raise ValueError(f"compaction must be 'immediate' or 'multipass', not {compaction!r}")
        self.compaction = compaction
        self.shadow_queue = compaction == "immediate"
        self.compactor = Compactor(self.queue, self.local_size) if compaction == "multipass" else None

    def run_pass(self, film, camera, seed, sample_base, spp):
        budget = camera["width"] * camera["height"] * spp
        size = min(self.stream_size, budget)
        capacity = np.int32(self.stream_capacity(size))
        stream, spare, shadow_rays = self.reused(("streams", size), lambda: (
            self.soa_buffer(PATH_STATE, size), self.soa_buffer(PATH_STATE, size),  # compaction writes to spare
            self.soa_buffer(SHADOW_RAY, size)))
        lane_counts, alive, shadow_steps, counters, indices = self.reused(("lanes", size), lambda: (
            self.lane_counts_buffer(size), self.int_buffer(size), self.int_buffer(size),
            self.int_buffer(len(StreamCounter)), self.compacted_indices(size)))
        radiance = self.output_buffer(budget)
        generate = self.kernel("pt_compact_regen_generate")

        length, next_id = 0, 0
        while True:
            # Regenerate: fill the end of the stream with the next samples of the budget.
            count = min(size - length, budget - next_id)
            if count > 0:
                self.launch(generate, count, camera, seed, np.int32(length), np.int32(count),
                            np.int32(next_id), np.int32(sample_base), capacity, stream)
                self.count_generate(count)
                length += count
                next_id += count
            if length == 0:
                break   # budget spent and the stream has drained
            # Extend every path by one vertex, then compact the survivors into `spare`.
            survivors, queued = self.extend_and_compact(seed, length, capacity, stream, spare, alive, counters,
                                                        shadow_rays, radiance, lane_counts, indices)
            self.count_extend_and_compact(lane_counts, length, size, draining=next_id == budget)
            # Trace the queued shadow rays: a packed stream of its own.
            if queued:
                self.launch(self.kernel("pt_compact_regen_shadow"), queued, *self.scene.args(),
                            np.int32(queued), capacity, shadow_rays, radiance, shadow_steps)
                self.count_shadow(shadow_steps, queued)
            stream, spare = spare, stream
            length = survivors
        self.collect(film, radiance, budget)

    def compacted_indices(self, size):
        """Multi-pass compaction's output (the survivors' indices) and the compactor's scratch
        memory, made with the streams: no iteration allocates. None for immediate compaction."""
        if self.compactor is None:
            return None
        self.compactor.reserve(size)
        return self.int_buffer(size)

    def extend_and_compact(self, seed, length, capacity, stream, spare, alive, counters, shadow_rays,
                           radiance, lane_counts, indices=None):
        """Returns (surviving paths, now packed at the start of `spare`; queued shadow rays)."""
        if self.compaction == "immediate":
            cl.enqueue_fill_buffer(self.queue, counters, np.int32(0), 0, 4 * len(StreamCounter))
            self.launch(self.kernel("pt_compact_regen_extend"), length, *self.scene.args(),
                        seed, np.int32(length), capacity, stream, spare, shadow_rays, counters,
                        radiance, lane_counts)
            lengths = self.read_ints(counters, len(StreamCounter))
            return int(lengths[StreamCounter.PATHS]), int(lengths[StreamCounter.SHADOW_RAYS])
        cl.enqueue_fill_buffer(self.queue, alive, np.int32(1), 0, 4 * length)   # every path in the stream is live
        self.launch(self.kernel("extend_in_place"), length, *self.scene.args(),
                    seed, np.int32(length), capacity, stream, alive, radiance, lane_counts)
        indices, survivors = self.compactor.compact_indices(alive, length, method="multipass", out=indices)
        if survivors:
            self.launch(self.kernel("pt_compact_regen_gather"), survivors,
                        np.int32(survivors), indices, capacity, stream, spare)
        return survivors, 0

    # --- SIMD counting: one hook per stage, no-ops unless count_simd ----------------------

    def count_generate(self, count):
        """Regeneration fills `count` consecutive stream entries: every lane busy."""
        if self.count_simd:
            self.simd.add_stream_step("generate", count)

    def count_extend_and_compact(self, lane_counts, length, size, draining):
        """The extension step over the `length` paths of the stream, and their compaction;
        `draining`: every sample of the budget has started (the final drain)."""
        if self.count_simd:
            self.count_stream_step(self.read_lane_counts(lane_counts, length), capacity=size, draining=draining)
            self.simd.add_stream_step("compact", length)

    def count_shadow(self, shadow_steps, queued):
        """The packed queue of `queued` shadow rays: every lane busy, traversal loops per warp."""
        if self.count_simd:
            self.simd.add_stream_step("shadow", queued)
            self.traversal.add_warp_loops("shadow", self.read_ints(shadow_steps, queued))
