"""When BDPT's evaluator lists the terminated samples (issue 48 check 1: reads per million samples).
Metropolis's iteration is one BDPT pass whose pool holds every chain, so its one connect phase
waits for the walk's end: the evaluator lists once the device's count of walk steps says earlier
passes' walks had ended, and no later than the step by which every subpath has ended."""
import numpy as np
import pyopencl as cl

from toolkit.core.layout import WalkCounter
from toolkit.opencl.device_scene import DeviceScene
from toolkit.techniques.bdpt_evaluator import BdptEvaluator, RECENT_WALKS
from toolkit.techniques.mlt import Mlt
from toolkit.techniques.pass_end import LAG


def test_an_mlt_iteration_lists_once_or_twice_and_walks_no_step_past_every_subpaths_end(monkeypatch, queue, cornell_box):
    """mlt on cornell_box (subpaths of up to MAX_VERTICES = 64 vertices), 256 chains in one pool,
    5 iterations (a naive start and 4 of mutations), then 2 more after a walk of 5 steps. Per
    iteration, looked at from outside: the last walk step that found subpaths (S: the streams'
    lengths read after every step), the listings, the reads (pyopencl's copies to the host) and
    the walk steps. The first pass knows
    no earlier walk: it lists once, at step MAX_VERTICES - 1, when every subpath has surely ended.
    Each pass teaches the evaluator its walk's length: the device's count equals S. A later pass
    lists at the longest of the last walks, once if its walk ended by then, else once more at
    MAX_VERTICES - 1; it reads only those listings and the current store's total. Before the
    device counted the steps, an iteration listed up to 8 times, walking up to 81 steps."""
    tech = Mlt(queue, DeviceScene(queue, cornell_box), chains=256, start="naive", count_simd=False)
    ev = tech.bdpt
    assert ev.regenerate_fraction == 1.0 and ev.pool_size >= 256 and ev.max_vertices == 64
    passes = []     # per pass: S, listings, reads, steps, first_at (the first listing's step), planned, learned
    real_copy, real_walk, real_list, real_read, real_start = (
        cl.enqueue_copy, BdptEvaluator.walk, BdptEvaluator.list_terminated, BdptEvaluator.listing_read,
        BdptEvaluator.start_pass)

    def copy(q, dest, src, **kwargs):
        if passes and "end" not in passes[-1] and not isinstance(dest, cl.MemoryObjectHolder):
            passes[-1]["reads"] += 1
        return real_copy(q, dest, src, **kwargs)

    def start_pass(self, *args, **kwargs):
        passes.append({"S": 0, "listings": 0, "reads": 0, "planned": max(self.walk_steps, default=None)})
        return real_start(self, *args, **kwargs)

    def walk(self, p):
        real_walk(self, p)
        counters = np.empty(WalkCounter.COUNTER_INTS, np.int32)
        real_copy(queue, counters, p.pool.counters)          # the step's lengths, read at once (not counted)
        if counters[WalkCounter.STEP_EYE_LENGTH] + counters[WalkCounter.STEP_LIGHT_LENGTH] > 0:
            passes[-1]["S"] = p.steps
        passes[-1]["steps"] = p.steps

    def list_terminated(self, p):
        passes[-1]["listings"] += 1
        passes[-1].setdefault("first_at", p.steps)
        return real_list(self, p)

    def listing_read(self, p):
        out = real_read(self, p)
        if out[1]:                                            # listed: the walk's length as the device counted it
            passes[-1]["learned"] = self.walk_steps[-1]
        return out

    end_render = tech.end_render
    with monkeypatch.context() as patch:
        patch.setattr(cl, "enqueue_copy", copy)
        for name, wrapper in (("walk", walk), ("list_terminated", list_terminated), ("listing_read", listing_read),
                              ("start_pass", start_pass)):
            patch.setattr(BdptEvaluator, name, wrapper)
        # the render's end reads the films, b and the tallies: not an iteration's
        patch.setattr(tech, "end_render", lambda film: (passes[-1].update(end=True), end_render(film)))
        tech.render(16, 16, 4, seed=5)      # a naive start and 4 iterations; the first knows no walk
        ev.walk_steps = [5]                 # as if the last walk had taken 5 steps: too few for the next
        tech.render(16, 16, 1, seed=6)      # a naive start and an iteration

    assert len(passes) == 7
    assert passes[5]["planned"] == 5 and passes[5]["S"] > 5 and passes[5]["listings"] == 2
    assert ev.walk_steps == [5, passes[5]["learned"], passes[6]["learned"]]      # its history since
    bound = ev.max_vertices - 1
    assert passes[0]["planned"] is None and passes[0]["listings"] == 1 and passes[0]["first_at"] == bound
    for k, one in enumerate(passes):
        assert one["learned"] == one["S"], (k, one)                # the device's count is the walk's length
        assert one["steps"] <= bound + LAG                         # no step after every subpath's end and the read
        if 0 < k < 5:
            assert one["planned"] == max(p["learned"] for p in passes[max(0, k - RECENT_WALKS):k])
        planned = bound if one["planned"] is None else min(bound, one["planned"])
        assert one["first_at"] == planned
        assert one["listings"] == (1 if one["S"] <= planned else 2), (k, one)
        # the listings' reads and the current store's total (mlt_chains.py Chains.kept), nothing else
        assert one["reads"] == one["listings"] + 1, (k, one)
    assert len({one["S"] for one in passes}) > 1                   # the walks differ: the schedule is tried
    assert any(one["listings"] == 1 for one in passes[1:])
