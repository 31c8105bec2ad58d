"""When a stream technique's pass is over, learned from the device without waiting for it.

A step of the stream launches its kernels over the whole stream: the counts on the device say
which work-items have work, and the others return at once (pbrt-v4's work queues do the same).
So the host needs no count to queue the next step; it only has to learn, in the end, that the
pass is over. Every `every` steps it queues a read of the last step's counts behind that step's
kernels, and looks at it `lag` steps later: by then the device has the next steps queued behind
the read, so the host waits for it without the device ever waiting for the host (a blocking read
after each step empties the device's queue every time). When the read says the pass was over,
the steps queued since found no work and left the image as it was. The counts it read (`latest`,
`lag` steps old) may also bound the later steps' launches.
"""

LAG = 2     # steps between queueing a read and looking at it: the device's work queued behind it


class PassEnd:
    """`over(counts)`: whether a step's counts (one value of `dtype`) say the pass is over.
    `at_least`: steps the pass takes in any case (the first read follows the last of them)."""

    def __init__(self, memory, dtype, over, every, at_least=1, lag=LAG):
        if not 1 <= lag <= every:
            raise ValueError(f"a read is looked at 1 to every ({every}) steps after it was queued, not {lag}")
        self.memory, self.dtype, self.over = memory, dtype, over
        self.every, self.at_least, self.lag = every, max(1, at_least), lag
        self.steps = 0
        self.pending = None     # (the read queued at the last checkpoint, its step), until looked at
        self.latest = None      # the counts of the last read the host has looked at (None before the first)

    def reached(self, counts):
        """After a step whose counts are in the device buffer `counts`: True once a read has said
        that the pass is over (`lag` to `every` + `lag` - 1 steps after it was)."""
        self.steps += 1
        if self.pending is not None and self.steps == self.pending[1] + self.lag:
            self.latest, self.pending = self.pending[0].result(), None
            if self.over(self.latest):
                return True
        if self.steps >= self.at_least and (self.steps - self.at_least) % self.every == 0:
            self.pending = (self.memory.read_later(counts, self.dtype), self.steps)
        return False
