"""When a stream technique's pass is over, learned from the device without waiting for it.

A step of the stream launches its kernels over the whole stream: the counts on the device say
which work-items have work, and the others return at once (pbrt-v4's work queues do the same).
So the host needs no count to queue the next step; it only has to learn, in the end, that the
pass is over. Every `every` steps it queues a read of the last step's counts behind that step's
kernels, and looks at the read it queued `every` steps before: a device that runs behind the
host did that one long ago, so the host waits for it without the device ever waiting for the
host (a blocking read after each step would empty the device's queue every time). When that
read says the pass was over, the steps queued since found no work and left the image as it was.
The counts it read (`latest`, some steps old) may also bound the later steps' launches.
"""


class PassEnd:
    """`over(counts)`: whether a step's counts (one value of `dtype`) say the pass is over.
    `at_least`: steps the pass takes in any case (the first read follows the last of them)."""

    def __init__(self, memory, dtype, over, every, at_least=1):
        self.memory, self.dtype, self.over = memory, dtype, over
        self.every, self.at_least = every, max(1, at_least)
        self.steps = 0
        self.pending = None     # the read queued at the last checkpoint
        self.latest = None      # the counts of the last read the host has looked at (None before the first)

    def reached(self, counts):
        """After a step whose counts are in the device buffer `counts`: True once a read has said
        that the pass is over (`every` steps or more after it was)."""
        self.steps += 1
        if self.steps < self.at_least or (self.steps - self.at_least) % self.every:
            return False
        if self.pending is not None:
            self.latest = self.pending.result()
            if self.over(self.latest):
                return True
        self.pending = self.memory.read_later(counts, self.dtype)
        return False
