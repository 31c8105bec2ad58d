"""Bidirectional path tracing with the plain connect phase: the work-item of each sample
slot loops over all the (s, t) connections of its sample once it has terminated (kernel:
cl/bdpt_naive_connect.cl); slots still walking idle.
The random walk (compacted eye/light streams, postponed regeneration) is shared with
bdpt_parallel_connect: see bdpt_base.py and cl/bdpt_walk.h."""
import numpy as np
import pyopencl as cl

from toolkit.core.simd import PhaseCounter
from toolkit.core.bdpt_indices import (naive_record_count, naive_splat_record, naive_strategy_record,
                                       naive_sum_record, strategy_count, strategy_index)
from toolkit.techniques.bdpt_base import BdptTechnique


class BdptNaiveConnect(BdptTechnique):
    name = "bdpt_naive_connect"
    source = "bdpt_naive_connect.cl"

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.packed_connect = PhaseCounter(self.warp_width)

    def extra_stats(self):
        stats = super().extra_stats()
        if self.count_simd:
            stats["connect_efficiency_terminated_packed"] = self.packed_connect.efficiency().get("connect")
        return stats

    def connect(self, p, count):
        npix = int(p.camera["width"] * p.camera["height"])
        if count == 0:
            return np.zeros((npix, 3))
        pool = p.pool.size
        # Where each terminated slot's light-tracing records go: a scan of their counts, so the
        # host reads back only the records written (before: MAX_VERTICES + 1 places per slot).
        counts, firsts = self.reused(("splat counts", pool), lambda: (self.int_buffer(pool), self.int_buffer(pool)))
        self.launch(self.kernel("bdpt_naive_connect_splats"), pool, np.int32(pool), p.pool.slots, counts)
        firsts, splats = self.compactor.exclusive_scan(counts, pool, out=firsts)
        # the splats, one eye-path sum per slot, and with per-strategy images a record per eye-path strategy of the short paths
        n = naive_record_count(splats, pool, self.record_strategy_count())
        capacity = 1 << max(12, (n - 1).bit_length())   # grows by powers of two, reused
        values, pixels = self.reused(("records", capacity), lambda: (
            cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE, 16 * capacity), self.int_buffer(capacity)))
        cl.enqueue_fill_buffer(self.queue, pixels, np.int32(-1), 0, 4 * n)   # records a slot may leave unwritten
        self.launch(self.kernel("bdpt_naive_connect"), pool, *self.scene.args(), p.camera,
                    np.int32(pool), np.int32(splats), firsts, p.pool.slots, p.pool.eye.vertices,
                    p.pool.light.vertices, values, pixels, p.pool.lane_counts)
        self.count_connect(p)
        values, pixels = self.read_records(values, pixels, n)
        if self.strategy_max_edges:
            values = self.keep_strategies(values, pixels, self.record_strategies(pool, self.read_ints(counts, pool)))
        return self.reduce_records(values, pixels, npix)

    def record_strategy_count(self):
        """Eye-path strategies with a record each: those of the per-strategy images, if any."""
        return strategy_count(self.strategy_max_edges) if self.strategy_max_edges else 0

    def record_strategies(self, pool, splat_counts):
        """The strategy index (toolkit/measure/strategies.py) of each record, placed where the kernel
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
        if not self.count_simd:
            return
        connections = self.read_lane_counts(p.pool.lane_counts, p.pool.size)["work"]
        self.simd.add_warp_loops("connect", connections)
        # For comparison: the same loops with only the terminated samples, packed side by side.
        self.packed_connect.add_warp_loops("connect", connections[connections > 0])
