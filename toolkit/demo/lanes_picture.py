"""The lanes picture: for a few warps, which lanes are busy at each step, drawn as a grid of
lanes (across) against steps (down), one coloured cell per busy lane.

What it samples. The SIMD counters (toolkit/core/simd.py, PhaseCounter) see every lane of every
step the techniques count per iteration: a boolean mask of the lanes that did the step's work
(in-place regeneration's slots, from the LaneCounts the kernels write), a count of lanes packed
at the start of a compacted stream (compaction, regeneration at the stream's end), or each
lane's number of loop iterations (pt_naive's one loop per path, where a lane is busy at
iteration k while its path has more than k vertices to go; the naive connect phase likewise, a
lane busy at iteration k while its sample has more than k connections to make, its slot idle
while its sample still walks). WarpSampler is a PhaseCounter that
counts as before and also keeps, for the steps that have an iteration number, the lanes of
`warps` warps spread over the launch (in-place regeneration: the same slots at every step; a
compacted stream: warps of the packed paths; pt_naive: warps of pixels across the image). A few
warps stand for all, as every warp of a launch does the same kind of work. Steps counted without
an iteration (shadow rays, a compaction, BDPT's regeneration) are in the efficiency figures only.

The final drain of a pass (every sample of its budget started, nothing regenerates, the stream
or the slots empty: the counters mark those steps `draining`) is one dark row in the picture, not
its steps: it is as long as the pass's longest path, and would fill the picture at the end of every
pass, hiding the steady state the talk's figures are about (a connect phase within it too). The
efficiency table counts it. Metropolis is the exception (`drains=True`): each of its iterations is
one batch of proposals, all started at once and none regenerated, so every walk step is a drain and
a picture without them would stay empty; there the drain is the lesson, and its steps are drawn.
"""
from collections import deque

import numpy as np

from toolkit.core.simd import PhaseCounter

SAMPLED_WARPS = 4     # warps drawn side by side
KEPT_STEPS = 96       # the most recent steps kept (rows of the picture)
GOLDEN = (5 ** 0.5 - 1) / 2

# RGBA colours: a busy lane by phase, an idle lane, and the gap between two warps.
BUSY = {"extend": (52, 120, 198, 255), "walk": (52, 120, 198, 255), "generate": (230, 126, 34, 255),
        "connect": (46, 160, 67, 255)}
BUSY_OTHER = (120, 80, 170, 255)  # any other phase: Metropolis's mutate and accept
DRAIN = "drain"                   # the marker row's phase
DRAIN_ROW = (70, 70, 70, 255)
IDLE = (225, 225, 225, 255)
GAP = (255, 255, 255, 255)


class WarpSampler(PhaseCounter):
    """A PhaseCounter that also keeps the lanes of `warps` warps of each counted step (a row: its
    phase and a boolean per lane), the last `kept` of them. `drains`: draw a drain's steps (Metropolis)
    instead of one marker row."""

    def __init__(self, warp_width=32, warps=SAMPLED_WARPS, kept=KEPT_STEPS, drains=False):
        super().__init__(warp_width)
        self.warps = warps
        self.drains = drains
        self.in_drain = False  # the last numbered step was a pass's final drain (and not drawn)
        self.rows = deque(maxlen=kept)
        self.steps = 0     # rows ever added: the picture changes when this does
        self._picks = (None, None)   # (launch size, its sampled_lanes): the last size seen

    def add_stream_step(self, phase, mask_or_count, length=None, iteration=None, capacity=None, draining=False):
        super().add_stream_step(phase, mask_or_count, length, iteration, capacity, draining)
        if iteration is None:
            return
        self.in_drain = draining and not self.drains
        if self.in_drain:     # the pass's final drain: one marker row for all of it (see the module's docstring)
            if not self.rows or self.rows[-1][0] != DRAIN:
                self.rows.append((DRAIN, np.zeros(self.warps * self.warp_width, bool)))
                self.steps += 1
            return
        if np.ndim(mask_or_count) == 0:       # a count of lanes packed at the start of the launch
            busy = np.ones(int(mask_or_count), bool)
        else:
            busy = np.asarray(mask_or_count, bool)
        self.rows.append((phase, self.sampled(busy)))
        self.steps += 1

    def add_loop_iterations(self, phase, lane_iterations, first_iteration=0):
        super().add_loop_iterations(phase, lane_iterations, first_iteration)
        if self.in_drain:      # a connect phase within the final drain: left out with it
            return
        x = self.sampled(np.asarray(lane_iterations, np.int64))
        # Each warp issues until its own longest lane is done: rows up to the sampled warps' longest.
        for k in range(int(x.max()) if len(x) else 0):
            self.rows.append((phase, x > k))
            self.steps += 1

    def sampled(self, lanes):
        """The lanes of `warps` warps spread over the launch, padded with idle lanes. Not its first
        warps (the image's top row, or a compacted stream's always-full head), nor evenly spaced
        ones: a pass is whole images of samples, so even spacing picks the same pixels in each.
        Golden-ratio steps land on warps far apart in the launch and in the image."""
        size, index = self._picks
        if size != len(lanes):   # only the last size is kept: a compacted stream's length changes every step
            index = sampled_lanes(len(lanes), self.warp_width, self.warps)
            self._picks = (len(lanes), index)
        out = np.zeros(len(index), lanes.dtype)
        drawn = index >= 0
        out[drawn] = lanes[index[drawn]]
        return out


def sampled_lanes(launched_lanes, warp_width, warps):
    """For WarpSampler.sampled: the index into a launch of `launched_lanes` lanes of each lane drawn,
    `warps` warps of `warp_width` lanes at golden-ratio steps over the launch; -1 where a picked warp
    runs past the launch's end, or fewer warps than `warps` were launched. Worked out once per
    launch size: in-place regeneration counts hundreds of steps a pass, all of the same size."""
    w, k = warp_width, warps
    launched = -(-launched_lanes // w)
    picks = np.unique((np.modf((np.arange(k) + 1) * GOLDEN)[0] * launched).astype(int)) if launched else []
    index = np.full(k * w, -1, np.int64)
    for i, warp in enumerate(picks):
        lanes = np.arange(warp * w, min((warp + 1) * w, launched_lanes))
        index[i * w:i * w + len(lanes)] = lanes
    return index


def lanes_picture(rows, warp_width, warps=SAMPLED_WARPS, steps=KEPT_STEPS):
    """An RGBA image (steps, warps x (W + 1) - 1, 4) of uint8: row i is the i-th of the last
    `steps` rows (phase, busy lanes), oldest at the top; each lane one pixel: busy in its
    phase's colour (BUSY), idle light grey (IDLE), and blank (GAP) where its warp did not issue
    the step at all (no lane busy: the counters count no issued lanes for it either); a pass's
    final drain is one dark row (DRAIN_ROW). A blank column separates two warps; rows not yet
    rendered are blank."""
    width = warps * (warp_width + 1) - 1
    picture = np.empty((steps, width, 4), np.uint8)
    picture[:] = GAP
    lane = np.arange(warps * warp_width)
    columns = lane + lane // warp_width         # warp w's lanes start at pixel w x (W + 1)
    for i, (phase, busy) in enumerate(list(rows)[-steps:]):
        if phase == DRAIN:
            picture[i, columns] = DRAIN_ROW
            continue
        busy = np.asarray(busy, bool)[:len(lane)]
        issued = np.repeat(busy.reshape(-1, warp_width).any(1), warp_width)
        picture[i, columns[issued]] = IDLE
        picture[i, columns[busy]] = BUSY.get(phase, BUSY_OTHER)
    return picture

