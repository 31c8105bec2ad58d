"""Assignment 2, parallel connect indexing (tutorials/assignments/parallel_connect/): the checks of
a student's cl/bdpt_parallel_connect.cl. The grader's kernel is parallel_connect_checks.cl beside
the stub."""
import numpy as np

from toolkit.core.layout import BDPT_SLOT
from toolkit.grading.assignment import Assignment, CheckFailed, same_image
from toolkit.opencl import program
from toolkit.techniques import BdptNaiveConnect, BdptParallelConnect

ASSIGNMENT = Assignment("parallel_connect", "Parallel connect indexing: scan and binary search",
                        "bdpt_parallel_connect.cl", "parallel_connect_stub.cl", ("parallel_connect_checks.cl",),
                        headers=("bdpt_walk.h",))


@ASSIGNMENT.builds
def build(c):
    """Everything the checks build."""
    _parallel_connect(c)
    c.technique(BdptNaiveConnect, student=False)


def _parallel_connect(c):
    tech = c.technique(BdptParallelConnect)
    return tech, c.build("parallel_connect_checks.cl", tech.defines)


def _search(c, counts):
    """find_sample for every connection g of the exclusive scan of `counts`: (found, expected, firsts)."""
    _, built = _parallel_connect(c)
    counts = np.asarray(counts, np.int32)
    firsts = (np.cumsum(counts) - counts).astype(np.int32)
    total = int(counts.sum())
    found = c.buffer(np.full(total, -1, np.int32))
    program.launch(c.queue, program.kernel(built, "grade_find_sample"), total, c.buffer(firsts),
                   np.int32(len(counts)), np.int32(total), found)
    expected = np.searchsorted(firsts, np.arange(total), side="right") - 1
    return c.read(found, np.int32, total), expected, firsts


def _search_problem(c, counts, what=""):
    found, expected, firsts = _search(c, counts)
    wrong = np.flatnonzero(found != expected)
    if len(wrong):
        g = wrong[0]
        e = expected[g]
        return (f"{what}connection {g} found sample {found[g]}, expected {e} (firsts[{e}] = {firsts[e]} <= {g}, "
                f"count {counts[e]}); {len(wrong)} of {len(found)} connections wrong")
    return None


@ASSIGNMENT.check("count", 20, "bdpt_parallel_connect_count: connections of each terminated sample, 0 otherwise")
def _check_count(c):
    tech, _ = _parallel_connect(c)
    rng = np.random.default_rng(6)
    n = 500
    slots = BDPT_SLOT.zeros(n)
    slots["live"] = rng.integers(-1, 3, n)
    slots["light_vertices"] = rng.integers(1, 9, n)
    slots["eye_vertices"] = rng.integers(2, 9, n)
    counts = c.buffer(np.full(program.padded(n), -1, np.int32))
    program.launch(c.queue, tech.kernel("bdpt_parallel_connect_count"), n, np.int32(n), c.buffer(slots), counts)
    got = c.read(counts, np.int32, n)
    expected = np.where(slots["live"] == 0, (slots["light_vertices"] + 1) * slots["eye_vertices"] - 1, 0)
    wrong = np.flatnonzero(got != expected)
    if len(wrong):
        i = wrong[0]
        raise CheckFailed(f"slot {i} (live {slots['live'][i]}, {slots['light_vertices'][i]} light and "
                          f"{slots['eye_vertices'][i]} eye vertices) has {got[i]} connections, expected {expected[i]}")


@ASSIGNMENT.check("search", 25, "find_sample for every connection, random counts with zeros")
def _check_search(c):
    rng = np.random.default_rng(7)
    for n in (300, 1000):
        counts = np.where(rng.random(n) < 0.3, 0, rng.integers(1, 40, n))
        problem = _search_problem(c, counts, f"{n} samples: ")
        if problem:
            raise CheckFailed(problem)


@ASSIGNMENT.check("search_edges", 20, "find_sample: one sample holds every connection, a pool of one, all ones")
def _check_search_edges(c):
    cases = []
    for k in (0, 150, 299):
        counts = np.zeros(300, np.int32)
        counts[k] = 500
        cases.append((f"all 500 connections in sample {k} of 300: ", counts))
    cases += [("a pool of one sample: ", np.array([37])), ("every count 1: ", np.ones(200, np.int32)),
              ("zeros at both ends: ", np.r_[np.zeros(5, np.int32), np.arange(1, 20), np.zeros(7, np.int32)])]
    for what, counts in cases:
        problem = _search_problem(c, counts, what)
        if problem:
            raise CheckFailed(problem)


@ASSIGNMENT.check("image", 35, "bdpt_parallel_connect with your kernel: the image of bdpt_naive_connect")
def _check_parallel_image(c):
    image = c.technique(BdptParallelConnect).render(16, 16, 4, seed=3).image()
    expected = c.technique(BdptNaiveConnect, student=False).render(16, 16, 4, seed=3).image()
    same_image(image, expected, "bdpt_naive_connect's", rtol=1e-4, atol=1e-6)
