"""The SIMD-efficiency model of the talk: active lanes divided by lanes issued, over warps of
W consecutive work-items. It is an upper bound on real SIMD efficiency and is counted the same
way on every device (a CPU runs idle lanes cheaply; the counters model a GPU warp)."""
from array import array
from collections.abc import Sequence

import numpy as np


class PhaseCounter:
    """Active and issued lane-steps per phase, summed over a render."""

    def __init__(self, warp_width=32):
        self.warp_width = warp_width
        self.active = {}
        self.issued = {}
        # per step, for plots: phase, iteration, efficiency, active lanes, stream capacity, and
        # whether the step belongs to the final drain (the budget is spent, nothing regenerates)
        self.per_iteration = StepFigures()

    def add(self, phase, active, issued):
        self.active[phase] = self.active.get(phase, 0) + int(active)
        self.issued[phase] = self.issued.get(phase, 0) + int(issued)

    def add_stream_step(self, phase, mask_or_count, length=None, iteration=None, capacity=None,
                        draining=False):
        """One kernel step over a stream: a warp issues the step if any of its lanes is active.
        `mask_or_count` is a boolean mask of active lanes, or a count of active lanes packed at
        the start of a stream of `length` (compacted streams). `draining`: the step runs after
        the pass's last sample has started, while the stream empties (marked on the plots)."""
        w = self.warp_width
        if isinstance(mask_or_count, (int, np.integer)) or np.ndim(mask_or_count) == 0:   # a count (the common case, tested first)
            active = int(mask_or_count)
            issued = -(-active // w) * w
        else:
            mask = np.asarray(mask_or_count, bool)
            pad = (-len(mask)) % w
            warps = np.concatenate([mask, np.zeros(pad, bool)]).reshape(-1, w)
            active = int(warps.sum())
            issued = int(warps.any(1).sum()) * w
        self.add_step(phase, active, issued, iteration, capacity or length, draining)

    def add_step(self, phase, active, issued, iteration=None, capacity=None, draining=False):
        """One step whose active and issued lanes are already summed (on the device:
        toolkit/opencl/simd_counters.py), numbered as add_stream_step numbers its steps."""
        self.add(phase, active, issued)
        if iteration is not None:
            self.per_iteration.add(phase, iteration, active, issued, capacity or active, draining)

    def add_warp_loops(self, phase, lane_iterations, active=None):
        """A loop run inside each lane: its warp issues as many iterations as its longest lane.
        `active` (default: the iterations themselves) counts the lane-steps doing the phase's work."""
        w = self.warp_width
        warps = _into_warps(lane_iterations, w)
        self.add(phase, warps.sum() if active is None else active, warps.max(1).sum() * w)

    def add_loop_iterations(self, phase, lane_iterations, first_iteration=0):
        """Per-iteration figures of a loop inside each lane (for plots): at iteration k the
        lanes with more than k iterations are active, the warps with any such lane issue."""
        w = self.warp_width
        x = np.asarray(lane_iterations, np.int64)
        longest = int(x.max()) if len(x) else 0
        # lanes (warps) with more than k iterations, for every k at once: counts of each length, summed from the top
        lanes_past = _more_than(x, longest)
        warps_past = _more_than(_into_warps(x, w).max(1), longest)
        self._add_iterations(phase, lanes_past, warps_past, len(x), first_iteration)

    def add_loop_histogram(self, phase, histogram, lanes, first_iteration=0):
        """add_loop_iterations from a histogram instead of the lanes: histogram[v] = (lanes whose loop
        ran v times, warps whose longest lane ran v times), over `lanes` lanes."""
        lanes_past = _from_the_top(histogram[:, 0])
        warps_past = _from_the_top(histogram[:, 1])
        # sums from the top never grow: the loop ran while any warp had iterations left
        running = int(np.count_nonzero(warps_past))
        self._add_iterations(phase, lanes_past[:running], warps_past[:running], lanes, first_iteration)

    def _add_iterations(self, phase, lanes_past, warps_past, capacity, first_iteration):
        """One per_iteration entry per iteration k of a loop: lanes_past[k] lanes and warps_past[k]
        warps still running it."""
        self.per_iteration.add_loop(phase, first_iteration, lanes_past, np.asarray(warps_past, np.int64) *
                                    self.warp_width, capacity)

    def efficiency(self):
        out = {p: (self.active[p] / self.issued[p] if self.issued[p] else 1.0) for p in self.active}
        total_issued = sum(self.issued.values())
        out["overall"] = sum(self.active.values()) / total_issued if total_issued else 1.0
        return out


def _into_warps(lane_iterations, warp_width):
    """Per-lane counts as rows of `warp_width` lanes (warps), the last warp padded with idle lanes (0)."""
    x = np.asarray(lane_iterations, np.int64)
    pad = (-len(x)) % warp_width
    return np.concatenate([x, np.zeros(pad, np.int64)]).reshape(-1, warp_width)


def _more_than(counts, longest):
    """For k = 0 .. longest - 1: how many of `counts` are greater than k."""
    at_least = np.bincount(counts, minlength=longest + 1)[::-1].cumsum()[::-1]   # at_least[k]: counts >= k
    return at_least[1:longest + 1]


def _from_the_top(counts_by_value):
    """For k = 0, 1, ...: how many counted values are greater than k, from counts by value."""
    return np.asarray(counts_by_value, np.int64)[::-1].cumsum()[::-1][1:]


class StepFigures(Sequence):
    """PhaseCounter.per_iteration: one figure per step or loop iteration, a dict of its phase,
    iteration, efficiency, active lanes, capacity and whether it drains. Kept as columns of numbers
    and made into dicts only when read: a counted render adds tens of thousands of them, and a dict
    each would be as many objects for Python's garbage collector to walk (a full collection of a
    render's process takes 13 to 18 ms, results/issue48_host_meter.md), for figures most renders
    never look at."""
    def __init__(self):
        self._phase = []                  # the phase's name (the same few strings, shared)
        self._iteration, self._active = array("q"), array("q")
        self._issued, self._capacity = array("q"), array("q")
        self._draining = array("b")
        self._made = []                   # the dicts made so far, for the first len(_made) figures

    def add(self, phase, iteration, active, issued, capacity, draining=False):
        """One step: `active` of `issued` lanes busy, over a stream of `capacity` lanes."""
        self._phase.append(phase)
        self._iteration.append(iteration)
        self._active.append(active)
        self._issued.append(issued)
        self._capacity.append(capacity)
        self._draining.append(bool(draining))

    def add_loop(self, phase, first_iteration, active, issued, capacity):
        """The iterations of a loop, numbered from `first_iteration`: `active[k]` of `issued[k]`
        lanes busy at its k-th (arrays), `capacity` lanes launched."""
        n = len(active)
        self._phase.extend([phase] * n)
        self._iteration.extend(range(first_iteration, first_iteration + n))
        self._active.frombytes(np.asarray(active, np.int64).tobytes())
        self._issued.frombytes(np.asarray(issued, np.int64).tobytes())
        self._capacity.frombytes(np.full(n, capacity, np.int64).tobytes())
        self._draining.frombytes(bytes(n))

    def __len__(self):
        return len(self._phase)

    def __getitem__(self, index):
        self._make()
        return self._made[index]

    def __iter__(self):
        self._make()
        return iter(self._made)

    def __eq__(self, other):
        return isinstance(other, Sequence) and len(self) == len(other) and list(self) == list(other)

    def __repr__(self):
        return f"StepFigures({list(self)!r})"

    def _make(self):
        """The dicts of the figures added since the last read (the efficiency as a step's active
        lanes over its issued ones, 1 for a step that issued none)."""
        made, total = len(self._made), len(self._phase)
        for k in range(made, total):
            active, issued = self._active[k], self._issued[k]
            self._made.append({"phase": self._phase[k], "iteration": self._iteration[k],
                               "efficiency": active / issued if issued else 1.0, "active": active,
                               "capacity": self._capacity[k], "draining": bool(self._draining[k])})
