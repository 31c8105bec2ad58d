"""Bidirectional path tracing with the plain connect phase: the work-item of each sample
slot loops over all the (s, t) connections of its sample once it has terminated (kernel:
cl/bdpt_naive_connect.cl); slots still walking idle.
The random walk (compacted eye/light streams, postponed regeneration) is shared with
bdpt_parallel_connect: see bdpt_evaluator.py and cl/bdpt_walk.h."""
import numpy as np

from toolkit.techniques.bdpt_evaluator import Connections, connect_args, record_buffers
from toolkit.core.layout import LONGEST_SUBPATH
from toolkit.core.bdpt_indices import (connection_count, naive_record_count, naive_splat_record, naive_strategy_record,
                                       naive_sum_record, strategy_count, strategy_index)
from toolkit.techniques.bdpt_base import BdptTechnique

PACKED = "connect_terminated_packed"   # the recorder's counter of the connect loops with only the terminated samples
MOST_CONNECTIONS = connection_count(LONGEST_SUBPATH, LONGEST_SUBPATH)   # of one sample: a lane's longest loop


class NaiveConnect:
    """The plain connect phase (cl/bdpt_naive_connect.cl), launched through `ctx` (a BdptContext):
    the light-tracing (t = 1) splats of each slot, then one sum of its eye-path strategies per slot.
    `strategy_max_edges`: the kernels keep strategies apart (STRATEGY_IMAGES)."""
    # Where each terminated slot's light-tracing records go: the evaluator scans their counts (so
    # the records are packed, not MAX_VERTICES + 1 places per slot) into p.pool.record_firsts.
    count_kernel = "bdpt_naive_connect_splats"

    def __init__(self, ctx, strategy_max_edges=None):
        self.ctx, self.strategy_max_edges = ctx, strategy_max_edges

    def __call__(self, p, count, splats):
        """The `count` samples listed (SLOT_CONNECTING) with `splats` light-tracing records (the listing's)."""
        ctx, pool = self.ctx, p.pool.size
        if count == 0:
            return Connections.none()
        # the splats, one eye-path sum per slot, and with per-strategy images a record per eye-path
        # strategy of the short paths; the kernel writes every record's pixel (-1: none)
        n = naive_record_count(splats, pool, self.record_strategy_count())
        values, pixels = record_buffers(ctx, n)
        k = ctx.kernels
        k.launch("bdpt_naive_connect", pool, **k.scene_args(), cam=p.camera, pool=k.int32(pool),
                 splats=np.int32(splats), **connect_args(p, p.pool.record_firsts, values, pixels, p.pool.lane_counts))
        self.count_connect(p)
        connections = Connections(n, values, pixels, ctx.queue)
        if self.strategy_max_edges:
            connections.strategy = self.record_strategies(pool, ctx.memory.read_ints(p.pool.record_counts, pool))
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
        """SIMD counters of the connect phase (a no-op unless count_simd), summed on the device: each
        lane's loop over its sample's connections (`work`), a warp issuing it as long as its longest
        lane, and the lanes of each iteration (for the per-iteration figures and the demo)."""
        ctx = self.ctx
        if not ctx.recorder.on:
            return
        def replay(recorder, sums):
            recorder.warp_loops(recorder.simd_counter(), "connect", sums, "work")
            recorder.loop_iterations("connect", sums, numbered=False)
            # For comparison: the same loops with only the terminated samples, packed side by side.
            recorder.packed_loops(recorder.counter(PACKED), "connect", sums)
        ctx.recorder.lanes(replay, p.pool.lane_counts, 4, p.pool.size, bins=MOST_CONNECTIONS + 1, packed=True)


class BdptNaiveConnect(BdptTechnique):
    name = "bdpt_naive_connect"
    source = "bdpt_naive_connect.cl"

    def connect_phase(self):
        return NaiveConnect(self.bdpt_context, self.strategy_max_edges)

    def extra_stats(self):
        stats = super().extra_stats()
        if self.count_simd:
            self.recorder.flush()
            stats["connect_efficiency_terminated_packed"] = self.recorder.counter(PACKED).efficiency().get("connect")
        return stats
