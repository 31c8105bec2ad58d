"""The SIMD-efficiency model of the talk: active lanes divided by lanes issued, over warps of
W consecutive work-items. It is an upper bound on real SIMD efficiency and is counted the same
way on every device (a CPU runs idle lanes cheaply; the counters model a GPU warp)."""
import numpy as np


class PhaseCounter:
    """Active and issued lane-steps per phase, summed over a render."""

    def __init__(self, warp_width=32):
        self.warp_width = warp_width
        self.active = {}
        self.issued = {}
        # per step, for plots: phase, iteration, efficiency, active lanes, stream capacity, and
        # whether the step belongs to the final drain (the budget is spent, nothing regenerates)
        self.per_iteration = []

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
            self.per_iteration.append({"phase": phase, "iteration": iteration,
                                       "efficiency": active / issued if issued else 1.0,
                                       "active": active, "capacity": capacity or active,
                                       "draining": bool(draining)})

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
        warps still running it. Python ints (tolist): a render counts tens of thousands of them."""
        w = self.warp_width
        lanes, warps = lanes_past.tolist(), warps_past.tolist()
        # by index, not zip: no tuple per iteration (a render makes thousands, each one more for the collector)
        self.per_iteration.extend(
            [{"phase": phase, "iteration": first_iteration + k,
              "efficiency": lanes[k] / (warps[k] * w) if warps[k] else 1.0,
              "active": lanes[k], "capacity": capacity, "draining": False} for k in range(len(lanes))])

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
