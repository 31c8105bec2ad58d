"""Bidirectional path tracing with the parallel connect phase (kernel:
cl/bdpt_parallel_connect.cl): connection counts -> exclusive scan -> one work-item per
connection, which finds its sample by binary search. Every lane of a warp evaluates one
connection, whatever the lengths of the subpaths."""
import numpy as np
import pyopencl as cl

from .bdpt_base import BdptTechnique


class BdptParallelConnect(BdptTechnique):
    name = "bdpt_parallel_connect"
    source = "bdpt_parallel_connect.cl"

    def connect(self, p, count):
        npix = int(p.camera["width"] * p.camera["height"])
        records = self.connection_records(p, count)
        return np.zeros((npix, 3)) if records is None else self.reduce_records(*records[:2], npix)

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
