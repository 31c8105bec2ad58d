"""PassEnd (toolkit/techniques/pass_end.py): the host learns that a stream technique's pass is over
from reads of the device's counts that it queued `lag` steps before, one every `every` steps,
never from one it has to wait for at once. A stand-in for the device memory records when each
read is queued and when its result is asked for; the pass is over after step `last`."""
import pytest

from toolkit.techniques.pass_end import PassEnd


class Reads:
    """DeviceMemory.read_later's stand-in: a read sees the counts at its place in the queue (the
    step it was queued after); `log` records (queued at step, looked at step) of each read."""

    def __init__(self):
        self.step = 0
        self.log = []

    def read_later(self, counts, dtype):
        reads, entry = self, [self.step, None]
        self.log.append(entry)
        value = counts(self.step)

        class Pending:
            def result(self):
                entry[1] = reads.step
                return value
        return Pending()


def run(last, every, at_least, lag):
    """Steps until PassEnd says the pass (over after step `last`) is over; and the reads."""
    reads = Reads()
    end = PassEnd(reads, None, lambda remaining: remaining == 0, every=every, at_least=at_least, lag=lag)
    while True:
        reads.step += 1
        if end.reached(lambda step: max(0, last - step)):
            return reads.step, reads.log, end.latest
        assert reads.step < 10 * (last + every + at_least), "PassEnd never ended the pass"


CASES = [(last, at_least) for last in (1, 2, 9, 10, 37, 68) for at_least in (0, 1, 9) if at_least <= last]


@pytest.mark.parametrize("every, lag", [(1, 1), (4, 1), (4, 2), (4, 4), (8, 2)])
@pytest.mark.parametrize("last, at_least", CASES)
def test_the_host_looks_at_a_read_lag_steps_after_it_was_queued(last, at_least, every, lag):
    stopped, log, latest = run(last, every, at_least, lag)
    assert latest == 0
    # Every read the host looked at was queued `lag` steps before: the device had that long.
    looked = [(queued, at) for queued, at in log if at is not None]
    assert looked and all(at - queued == lag for queued, at in looked), log
    # No read before the steps the pass takes in any case, then one every `every` steps.
    first = max(at_least, 1)
    queued = [step for step, _ in log]
    assert queued == list(range(first, queued[-1] + 1, every))
    # The first read after the end says so, and the host acts on it `lag` steps later:
    # it queued between `lag` and every + lag - 1 steps that found no work.
    said = next(step for step in queued if step >= last)
    assert stopped == said + lag
    assert lag <= stopped - last <= every + lag - 1


def test_a_read_is_looked_at_before_the_next_is_queued():
    with pytest.raises(ValueError, match="1 to every"):
        PassEnd(Reads(), None, bool, every=2, lag=3)
