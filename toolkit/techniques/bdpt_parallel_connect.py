"""Bidirectional path tracing with the parallel connect phase (kernel:
cl/bdpt_parallel_connect.cl): connection counts -> exclusive scan -> one work-item per
connection, which finds its sample by binary search. Every lane of a warp evaluates one
connection, whatever the lengths of the subpaths."""
import numpy as np
import pyopencl as cl

from toolkit.core.bdpt_indices import connection_strategy
from toolkit.core.layout import BDPT_SLOT
from toolkit.techniques.strategy_images import strategy_index
from toolkit.techniques.bdpt_base import BdptTechnique


class BdptParallelConnect(BdptTechnique):
    name = "bdpt_parallel_connect"
    source = "bdpt_parallel_connect.cl"

    def connect(self, p, count):
        npix = int(p.camera["width"] * p.camera["height"])
        records = self.connection_records(p, count)
        if records is None:
            return np.zeros((npix, 3))
        values, pixels, counts = records
        if self.strategy_max_edges:
            values = self.keep_strategies(values, pixels, self.record_strategies(p, counts))
        return self.reduce_records(values, pixels, npix)

    def record_strategies(self, p, counts):
        """The strategy index (toolkit/measure/strategies.py) of each connection record: a slot's records
        are consecutive, local index k is strategy (s, t) with k + 1 = (t - 1)(n_light + 1) + s
        (connection_strategy, toolkit/core/bdpt_indices.py, as the kernel computes it)."""
        counts = self.read_ints(counts, p.pool.size)
        n_light = self.read_structs(BDPT_SLOT, p.pool.slots, p.pool.size)["light_vertices"].astype(np.int64)
        firsts = np.cumsum(counts) - counts
        slot = np.repeat(np.arange(p.pool.size), counts)
        s, t = connection_strategy(np.arange(counts.sum()) - firsts[slot], n_light[slot])
        return strategy_index(s, t, self.strategy_max_edges)

    def connection_records(self, p, count):
        """Evaluate every connection of the terminated samples: (values (n, 4) float32, pixels (n,),
        the device buffer of connection counts per pool slot), or None when there is none.
        The records of one slot are consecutive, in slot order."""
        pool = p.pool.size
        if count == 0:
            return None
        counts, firsts = self.reused(("counts", pool), lambda: (self.int_buffer(pool), self.int_buffer(pool)))
        self.launch(self.kernel("bdpt_parallel_connect_count"), pool, np.int32(pool),
                    p.pool.slots, counts)
        firsts, total = self.compactor.exclusive_scan(counts, pool, out=firsts)
        if total == 0:
            return None
        # Record buffers grow by powers of two and are reused by the next connect phases.
        capacity = 1 << max(12, (total - 1).bit_length())
        values, pixels, lanes = self.reused(("records", capacity), lambda: (
            cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE, 16 * capacity),
            self.int_buffer(capacity), self.lane_counts_buffer(capacity)))
        self.launch(self.kernel("bdpt_parallel_connect"), total, *self.scene.args(), p.camera,
                    np.int32(total), np.int32(pool), firsts, p.pool.slots, p.pool.eye.vertices,
                    p.pool.light.vertices, values, pixels, lanes)
        if self.count_simd:
            self.simd.add_stream_step("connect", total)
        return (*self.read_records(values, pixels, total), counts)
