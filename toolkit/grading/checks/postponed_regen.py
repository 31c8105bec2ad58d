"""Assignment 5, postponed regeneration (tutorials/assignments/postponed_regen/): the checks of a
student's cl/bdpt_regeneration.h, whose bdpt_regeneration_sample (called by cl/bdpt_walk.h's bdpt_regenerate) says which sample each lane of BDPT's
regeneration launch starts in its terminated slot, or that the slot goes idle (budget spent)."""
import numpy as np
import pyopencl as cl

from toolkit.core.layout import BDPT_SLOT, SlotState
from toolkit.grading.assignment import Assignment, CheckFailed, same_image
from toolkit.techniques import BdptParallelConnect

ASSIGNMENT = Assignment("postponed_regen", "Postponed regeneration: BDPT's sample pool", "bdpt_regeneration.h",
                        "postponed_regen_stub.cl",
                        headers=("common.h",))


@ASSIGNMENT.builds
def build(c):
    """Everything the checks build: BDPT with the submission's walk, and the toolkit's."""
    for student in (True, False):
        c.technique(BdptParallelConnect, student)


_UNTOUCHED = -7   # fills the pool's slots before a launch: slots that must not change keep it


def _regenerate(c, listed, first, budget):
    """One regeneration launch of the submission's bdpt_regenerate (through the toolkit's host code,
    BdptEvaluator.regenerate) on a pool whose terminated slots are `listed`, the next sample id
    `first`: the pool's slots after it, as a BdptSlot array."""
    tech = c.technique(BdptParallelConnect)
    p = tech.bdpt.start_pass(tech.scene.camera(64, 64), c.seed(1), 0, budget)
    size = p.pool.size
    cl.enqueue_fill_buffer(c.queue, p.pool.slots, np.int32(_UNTOUCHED), 0, BDPT_SLOT.dtype.itemsize * size)
    p.next_id = first
    tech.bdpt.regenerate(p, c.buffer(np.asarray(listed, np.int32)), len(listed))
    return c.read(p.pool.slots, BDPT_SLOT.dtype, size), size


def _listed(c, size):
    """The terminated slots of a synthetic pool, in the order compaction lists them (ascending)."""
    return np.flatnonzero(c.rng(8).random(size) < 0.6)


def _started(slots, listed):
    return [int(s) for s in slots["sample_id"][listed]], slots["live"][listed]


@ASSIGNMENT.check("ids", 40, "every listed slot starts the next sample, in list order, once each; other slots "
                  "are left alone", "lane i of the launch owns the i-th listed slot and the i-th of the fresh sample "
                  "ids, which follow the pool's next id one by one (consecutive pixels)")
def _check_ids(c):
    tech = c.technique(BdptParallelConnect)
    size = min(tech.pool_size, 100000)
    listed = _listed(c, size)
    first = 1234
    slots, size = _regenerate(c, listed, first, 100000)
    ids, live = _started(slots, listed)
    expected = list(range(first, first + len(listed)))
    for lane, (got, want) in enumerate(zip(ids, expected)):
        if got != want or live[lane] == _UNTOUCHED:
            did = "started nothing" if live[lane] == _UNTOUCHED or live[lane] == SlotState.IDLE else f"started sample {got}"
            raise CheckFailed(f"{len(listed)} listed slots, next id {first}: lane {lane} (slot {listed[lane]}) "
                              f"{did}, expected sample {want}")
    others = np.setdiff1d(np.arange(size), listed)
    touched = others[slots["live"][others] != _UNTOUCHED]
    if len(touched):
        raise CheckFailed(f"slot {touched[0]} was not listed and was written")


@ASSIGNMENT.check("budget", 20, "when the budget runs out, exactly the samples left are started and the other "
                  "listed slots go idle", "the launch has one lane per terminated slot but only as many fresh "
                  "samples as the pass has left; a lane past them must start nothing")
def _check_budget(c):
    tech = c.technique(BdptParallelConnect)
    size = min(tech.pool_size, 100000)
    listed = _listed(c, size)
    first = 5000
    left = len(listed) // 3
    slots, _ = _regenerate(c, listed, first, first + left)
    live = slots["live"][listed]
    started = int((live == SlotState.BOTH_WALKING).sum())
    idle = np.flatnonzero(live[left:] != SlotState.IDLE)
    if started != left or len(idle):
        raise CheckFailed(f"{len(listed)} listed slots, {left} samples left: {started} started"
                          + (f", lane {left + idle[0]} is not idle" if len(idle) else ""))


def _sane(c):
    """Whether every lane within the samples left starts one (else the walk reads subpaths never written)."""
    tech = c.technique(BdptParallelConnect)
    listed = np.arange(0, min(tech.pool_size, 100000), 2)
    slots, _ = _regenerate(c, listed, 0, 100000)
    return bool(np.all(slots["live"][listed] == SlotState.BOTH_WALKING))


@ASSIGNMENT.check("image", 40, "bdpt_parallel_connect with your regeneration: the toolkit's image, sample for sample",
                  "each sample id of the budget must be started exactly once, so that every pixel gets its samples "
                  "and the image is the toolkit's sample for sample", hidden=True)
def _check_image(c):
    if not _sane(c):
        raise CheckFailed("not rendered: some lanes within the budget start no sample, so the walk would read "
                          "subpaths that were never written")
    films = [c.technique(BdptParallelConnect, student).render(24, 16, 8, seed=c.seed(2)) for student in (True, False)]
    same_image(films[0].image(), films[1].image(), "the toolkit's bdpt_parallel_connect", rtol=0, atol=0)
    if not np.array_equal(films[0].count, films[1].count):
        raise CheckFailed("the samples per pixel differ from the toolkit's")
