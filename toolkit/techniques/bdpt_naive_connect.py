"""Bidirectional path tracing with the plain connect phase: the work-item of each sample
slot loops over all the (s, t) connections of its sample once it has terminated (kernel:
cl/bdpt_naive_connect.cl); slots still walking idle.
The random walk (compacted eye/light streams, postponed regeneration) is shared with
bdpt_parallel_connect: see bdpt_evaluator.py and cl/bdpt_walk.h."""
import numpy as np
import pyopencl as cl

from toolkit.core.simd import PhaseCounter
from toolkit.techniques.bdpt_evaluator import Connections, connect_args, record_buffers, scan_slot_counts
from toolkit.core.bdpt_indices import (naive_record_count, naive_splat_record, naive_strategy_record,
                                       naive_sum_record, strategy_count, strategy_index)
from toolkit.techniques.bdpt_base import BdptTechnique


class NaiveConnect:
    """The plain connect phase (cl/bdpt_naive_connect.cl), launched through `ctx` (a BdptContext):
    the light-tracing (t = 1) splats of each slot, then one sum of its eye-path strategies per slot.
    `strategy_max_edges`: the kernels keep strategies apart (STRATEGY_IMAGES)."""

    def __init__(self, ctx, strategy_max_edges=None):
        self.ctx, self.strategy_max_edges = ctx, strategy_max_edges
        self.packed = PhaseCounter(ctx.recorder.warp_width)   # the connect loops with only the terminated samples
        self.counts = self.firsts = None   # the splat counts of the listed slots and their scan (prepare)

    def prepare(self, p):
        """Where each terminated slot's light-tracing records will go: a scan of their counts (so
        the records are packed, not MAX_VERTICES + 1 places per slot), on the device. Returns the
        one-int buffer of the splats' total."""
        self.counts, self.firsts, splats = scan_slot_counts(self.ctx, p, "bdpt_naive_connect_splats", "splat counts")
        return splats

    def __call__(self, p, count, splats):
        """The `count` samples listed (SLOT_CONNECTING) with `splats` light-tracing records (prepare's total)."""
        ctx, pool = self.ctx, p.pool.size
        if count == 0:
            return Connections.none()
        # the splats, one eye-path sum per slot, and with per-strategy images a record per eye-path strategy of the short paths
        n = naive_record_count(splats, pool, self.record_strategy_count())
        values, pixels = record_buffers(ctx, n)
        cl.enqueue_fill_buffer(ctx.queue, pixels, np.int32(-1), 0, 4 * n)   # records a slot may leave unwritten
        ctx.kernels.launch("bdpt_naive_connect", pool, **ctx.kernels.scene_args(), cam=p.camera, pool=np.int32(pool),
                    splats=np.int32(splats), **connect_args(p, self.firsts, values, pixels, p.pool.lane_counts))
        self.count_connect(p)
        connections = Connections(n, values, pixels, ctx.queue)
        if self.strategy_max_edges:
            connections.strategy = self.record_strategies(pool, ctx.memory.read_ints(self.counts, pool))
        return connections

    def record_strategy_count(self):
        """Eye-path strategies with a record each: those of the per-strategy images, if any."""
        return strategy_count(self.strategy_max_edges) if self.strategy_max_edges else 0

    def record_strategies(self, pool, splat_counts):
        """The strategy index (strategy_images.strategy_index) of each record, placed where the kernel
        put it (toolkit/core/bdpt_indices.py): the t = 1 splats of s = 1 .. splat_counts[k] of each
        slot k, one sum of the longer paths per slot, one record per short eye-path strategy."""
        count, splats = self.record_strategy_count(), int(splat_counts.sum())
        index = np.empty(naive_record_count(splats, pool, count), np.int64)
        slot = np.repeat(np.arange(pool), splat_counts)
        firsts = np.cumsum(splat_counts) - splat_counts
        splat_s = np.arange(splats) - firsts[slot] + 1
        index[naive_splat_record(firsts[slot], splat_s)] = strategy_index(splat_s, 1, self.strategy_max_edges)
        index[naive_sum_record(splats, np.arange(pool))] = count
        slot, strategy = np.divmod(np.arange(pool * count), count)
        index[naive_strategy_record(splats, pool, slot, strategy, count)] = strategy
        return index

    def count_connect(self, p):
        ctx = self.ctx
        if not ctx.recorder.on:
            return
        connections = ctx.memory.read_lane_counts(p.pool.lane_counts, p.pool.size)["work"]
        ctx.recorder.inner_loop("connect", connections)     # and the lanes of each iteration, for the demo
        # For comparison: the same loops with only the terminated samples, packed side by side.
        self.packed.add_warp_loops("connect", connections[connections > 0])


class BdptNaiveConnect(BdptTechnique):
    name = "bdpt_naive_connect"
    source = "bdpt_naive_connect.cl"

    def connect_phase(self):
        return NaiveConnect(self.bdpt_context, self.strategy_max_edges)

    def extra_stats(self):
        stats = super().extra_stats()
        if self.count_simd:
            stats["connect_efficiency_terminated_packed"] = self.bdpt.connect.packed.efficiency().get("connect")
        return stats
