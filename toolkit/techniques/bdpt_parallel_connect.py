"""Bidirectional path tracing with the parallel connect phase (kernel:
cl/bdpt_parallel_connect.cl): connection counts -> exclusive scan -> one work-item per
connection, which finds its sample by binary search. Every lane of a warp evaluates one
connection, whatever the lengths of the subpaths."""
import numpy as np

from toolkit.core.bdpt_indices import connection_strategy
from toolkit.core.layout import BDPT_SLOT
from toolkit.techniques.bdpt_evaluator import Connections, connect_args, record_buffers
from toolkit.techniques.strategy_images import strategy_index
from toolkit.techniques.bdpt_base import BdptTechnique


class ParallelConnect:
    """The parallel connect phase (cl/bdpt_parallel_connect.cl), launched through `ctx` (a
    BdptContext). Its records of one slot are consecutive, in slot order. `strategy_max_edges`: the kernels keep
    strategies apart (STRATEGY_IMAGES), and each record gets its strategy; `read_slots`: the
    Connections carry the slots and their record counts (which sample each record belongs to)."""
    # Step 1 for the terminated samples (SLOT_TERMINATED): their connection counts. The evaluator
    # lists them and scans the counts (step 2) into p.pool.record_firsts.
    count_kernel = "bdpt_parallel_connect_count"

    def __init__(self, ctx, strategy_max_edges=None, read_slots=False):
        self.ctx, self.strategy_max_edges = ctx, strategy_max_edges
        self.read_slots = read_slots or bool(strategy_max_edges)

    def __call__(self, p, count, total):
        """Every connection (`total`, the listing's) of the `count` samples listed then (SLOT_CONNECTING)."""
        ctx, pool = self.ctx, p.pool.size
        counts, firsts = p.pool.record_counts, p.pool.record_firsts
        if count == 0 or total == 0:
            return Connections.none()
        values, pixels, lanes = record_buffers(ctx, total, ctx.memory.lane_counts_buffer)
        k = ctx.kernels
        k.launch("bdpt_parallel_connect", total, **k.scene_args(), cam=p.camera,
                 total=np.int32(total), pool=k.int32(pool), **connect_args(p, firsts, values, pixels, lanes))
        if ctx.recorder.on:
            ctx.recorder.before_step("connect", total)
        connections = Connections(total, values, pixels, ctx.queue, slot_buffer=p.pool.slots, count_buffer=counts,
                                  first_buffer=firsts)
        if self.read_slots:
            connections.slot_records = ctx.memory.read_ints(counts, pool)
            connections.slots = ctx.memory.read_structs(BDPT_SLOT, p.pool.slots, pool)
        if self.strategy_max_edges:
            connections.strategy = self.record_strategies(connections)
        return connections

    def record_strategies(self, connections):
        """The strategy index (strategy_images.strategy_index) of each connection record: a slot's
        records are consecutive, local index k is strategy (s, t) with k + 1 = (t - 1)(n_light + 1) + s
        (connection_strategy in cl/bdpt.h)."""
        counts = connections.slot_records
        n_light = connections.slots["light_vertices"].astype(np.int64)
        firsts = np.cumsum(counts) - counts
        slot = np.repeat(np.arange(len(counts)), counts)
        s, t = connection_strategy(np.arange(counts.sum()) - firsts[slot], n_light[slot])
        return strategy_index(s, t, self.strategy_max_edges)


class BdptParallelConnect(BdptTechnique):
    name = "bdpt_parallel_connect"
    source = "bdpt_parallel_connect.cl"

    def connect_phase(self):
        return ParallelConnect(self.bdpt_context, self.strategy_max_edges)
