"""Assignment 1, in-place sample regeneration (tutorials/assignments/inplace_regen/): the checks of a
student's cl/pt_inplace_regen.cl."""
import numpy as np
import pyopencl as cl

from toolkit.core.layout import PATH_STATE, PT_PASS
from toolkit.grading.assignment import Assignment, CheckFailed, same_image
from toolkit.opencl import program
from toolkit.techniques import PtInplaceRegen

ASSIGNMENT = Assignment("inplace_regen", "In-place sample regeneration", "pt_inplace_regen.cl",
                        "inplace_regen_stub.cl", headers=("extend_in_place.h", "pt_inplace_regen_kernels.h"))


@ASSIGNMENT.builds
def build(c):
    """Everything the checks build."""
    for student in (True, False):
        c.technique(PtInplaceRegen, student)


_UNTOUCHED = -7   # fills the path records before a launch: slots that must not change keep it


def _regenerate(c, alive, next_sample, budget):
    """Run the submission's pt_inplace_regen_regenerate on one pool: the slot's sample ids after it
    (PathState.slot; _UNTOUCHED where nothing was written), alive flags, any_alive, regenerated."""
    tech = c.technique(PtInplaceRegen)
    n = len(alive)
    capacity = program.padded(n)
    paths = PATH_STATE.soa_buffer(c.queue.context, capacity)
    cl.enqueue_fill_buffer(c.queue, paths, np.int32(_UNTOUCHED), 0, paths.size)
    flags, counter = c.buffer(np.r_[alive, np.zeros(capacity - n)].astype(np.int32)), c.buffer(np.int32([next_sample]))
    any_alive, regenerated = c.buffer(np.zeros(1, np.int32)), c.buffer(np.full(capacity, -1, np.int32))
    camera = tech.scene.camera(16, 16)
    pass_args = PT_PASS.record(seed=c.seed(1), sample_base=0, budget=budget, capacity=capacity)
    program.launch(c.queue, tech.kernels.kernel("pt_inplace_regen_regenerate"), n, camera, pass_args, np.int32(n),
                   counter, paths, flags, any_alive, regenerated)
    ids = c.read(paths, np.int32, n, PATH_STATE.soa_offset("slot", capacity))
    return (ids, c.read(flags, np.int32, n), int(c.read(any_alive, np.int32, 1)[0]),
            c.read(regenerated, np.int32, n))


def _pools(c):
    rng = c.rng(8)
    alive = (rng.random(1000) < 0.5).astype(np.int32)
    free = int((alive == 0).sum())
    return [("1000 slots, every free slot gets a sample: ", alive, 100, 100000),
            ("1000 slots, the budget runs out: ", alive, 100, 100 + free // 2)]


@ASSIGNMENT.check("ids", 30, "free slots start the next samples of the budget, once each; live slots are left alone",
                  "a shared atomic counter hands out sample ids, one per free slot; an id at or past the budget starts nothing")
def _check_ids(c):
    for what, alive, first, budget in _pools(c):
        ids, flags, _, _ = _regenerate(c, alive, first, budget)
        free = np.flatnonzero(alive == 0)
        started = free[ids[free] != _UNTOUCHED]
        touched = np.flatnonzero((alive != 0) & (ids != _UNTOUCHED))
        if len(touched):
            raise CheckFailed(f"{what}slot {touched[0]} held a live path and was overwritten")
        expected = np.arange(first, min(budget, first + len(free)))
        got = np.sort(ids[started])
        if len(got) != len(expected) or np.any(got != expected):
            extra = np.setdiff1d(got, expected)
            missing = np.setdiff1d(expected, got)
            detail = (f"sample {extra[0]} is not in {first} .. {budget - 1}" if len(extra) else
                      f"sample {missing[0]} was not started" if len(missing) else "a sample was started twice")
            raise CheckFailed(f"{what}{len(got)} samples started, expected {len(expected)} "
                              f"({first} .. {expected[-1] if len(expected) else first - 1}): {detail}")
        wrong = np.flatnonzero(flags != ((alive != 0) | (ids != _UNTOUCHED)))
        if len(wrong):
            raise CheckFailed(f"{what}slot {wrong[0]}: alive is {flags[wrong[0]]} after the step")


@ASSIGNMENT.check("any_alive", 15, "any_alive: set when a slot holds a live path, left 0 when all are done",
                  "any_alive tells the host whether another step is needed: a slot counts if it holds a live path after this "
                  "step, whether that path is old or just started")
def _check_any_alive(c):
    n = 1000
    one = np.zeros(n, np.int32)
    one[517] = 1
    cases = [("free slots and samples left", np.zeros(n, np.int32), 0, 5000, 1),
             ("budget spent, one path still alive", one, 5000, 5000, 1),
             ("budget spent, every path ended", np.zeros(n, np.int32), 5000, 5000, 0)]
    for what, alive, first, budget, expected in cases:
        got = _regenerate(c, alive, first, budget)[2]
        if got != expected:
            raise CheckFailed(f"{what}: any_alive is {got}, expected {expected}")


@ASSIGNMENT.check("regenerated", 10, "regenerated[] marks the lanes that started a sample (SIMD counters)",
                  "the SIMD counters need to know which lanes did the work of starting a sample in this step, and only those")
def _check_regenerated(c):
    for what, alive, first, budget in _pools(c):
        free = np.flatnonzero(alive == 0)
        expected = np.zeros(len(alive), np.int32)
        expected[free[:max(0, min(len(free), budget - first))]] = 1   # how many; which ones may vary
        got = _regenerate(c, alive, first, budget)[3]
        if np.any((got != 0) & (alive != 0)) or int((got != 0).sum()) != int(expected.sum()):
            raise CheckFailed(f"{what}regenerated[] marks {int((got != 0).sum())} lanes, "
                              f"{int(expected.sum())} started a sample")


@ASSIGNMENT.check("image", 45, "pt_inplace_regen with your kernel: the toolkit's image, sample for sample",
                  "each sample id must be started exactly once, with the pass's seed and sample base, so that the image is "
                  "the toolkit's sample for sample", hidden=True)
def _check_regen_image(c):
    films = [c.technique(PtInplaceRegen, student, stream_size=256).render(15, 9, 8, seed=c.seed(2))   # 1080 samples,
             for student in (True, False)]                                                  # 256 slots
    same_image(films[0].image(), films[1].image(), "the toolkit's pt_inplace_regen", rtol=0, atol=0)
    if not np.array_equal(films[0].count, films[1].count):
        raise CheckFailed("the samples per pixel differ from the toolkit's")
