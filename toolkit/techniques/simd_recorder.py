"""A technique's SIMD counters (toolkit/core/simd.py): which lanes each step kept busy, and the
iteration each step belongs to, for the per-iteration plots. Off (count_simd=False), the
techniques skip the reads that feed it."""
from toolkit.core.simd import PhaseCounter


class SimdRecorder:
    def __init__(self, warp_width, on=True):
        self.warp_width = warp_width
        self.on = bool(on)
        self.simd = PhaseCounter(warp_width)        # lanes busy per phase (extend, generate, connect, ...)
        self.traversal = PhaseCounter(warp_width)   # BVH traversal loops per warp (closest, shadow)
        self.iterations = 0    # extension steps (loop iterations for pt_naive) over all passes so far

    def step(self, phase, active, capacity=None, draining=False):
        """One step of the stream's loop (an extension, a walk step), numbered: `active` lanes
        (a count or a mask), `capacity` the stream's size (for the occupancy plot), `draining`
        whether no sample is left to start (the final drain)."""
        self.simd.add_stream_step(phase, active, iteration=self.iterations, capacity=capacity, draining=draining)
        self.iterations += 1

    def before_step(self, phase, active, capacity=None, draining=False):
        """A step numbered as the step that follows it (a regeneration, counted with the
        extension it feeds)."""
        self.simd.add_stream_step(phase, active, iteration=self.iterations, capacity=capacity, draining=draining)

    def loop(self, phase, iterations):
        """A loop that each work-item runs `iterations[k]` times (pt_naive's whole path): a warp
        issues it as long as its longest lane; its iterations are numbered from the steps so far."""
        self.simd.add_warp_loops(phase, iterations)
        self.simd.add_loop_iterations(phase, iterations, first_iteration=self.iterations)
        self.iterations += int(iterations.max())

    def inner_loop(self, phase, iterations):
        """A loop that each work-item of one launch runs `iterations[k]` times, between two steps
        (the naive connect phase: a lane's connections): a warp issues it as long as its longest
        lane; its iterations are numbered as the step that follows, as before_step's."""
        self.simd.add_warp_loops(phase, iterations)
        self.simd.add_loop_iterations(phase, iterations, first_iteration=self.iterations)

    def extension_step(self, lanes, capacity, draining=False, shadow_queue=False):
        """SIMD counters of one extension step over a stream, from the LaneCounts of the lanes
        that ran it; with `shadow_queue` the shadow rays are traced (and counted) by a kernel
        of their own, else inside the step."""
        self.step("extend", lanes["work"] > 0, capacity=capacity, draining=draining)
        self.traversal.add_warp_loops("closest", lanes["closest_steps"])
        if not shadow_queue:
            self.simd.add_stream_step("shadow", lanes["shadow_rays"] > 0)
            self.traversal.add_warp_loops("shadow", lanes["shadow_steps"])

    def efficiency(self):
        """SIMD efficiency per phase ({} when off)."""
        return self.simd.efficiency() if self.on else {}
