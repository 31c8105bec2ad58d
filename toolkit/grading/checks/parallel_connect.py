"""Assignment 3, parallel connect indexing (tutorials/assignments/parallel_connect/): the checks of
a student's cl/bdpt_parallel_connect.cl. The grader's kernel is parallel_connect_checks.cl beside
the stub."""
import re
import shutil
from pathlib import Path

import numpy as np

from toolkit.core.layout import BDPT_SLOT
from toolkit.grading import instrument
from toolkit.grading.assignment import Assignment, CheckFailed, same_image
from toolkit.opencl import program
from toolkit.techniques import BdptNaiveConnect, BdptParallelConnect

ASSIGNMENT = Assignment("parallel_connect", "Parallel connect indexing: scan and binary search",
                        "bdpt_parallel_connect.cl", "parallel_connect_stub.cl", ("parallel_connect_checks.cl",),
                        headers=("bdpt_walk.h",))


@ASSIGNMENT.builds
def build(c):
    """Everything the checks that run build."""
    _parallel_connect(c)
    if c.runs("image"):
        c.technique(BdptNaiveConnect, student=False)
        c.technique(BdptParallelConnect, folder=_variant(c, "reference_parts", _with_reference_parts(c, _student(c))))


def _parallel_connect(c):
    tech = c.technique(BdptParallelConnect)
    return tech, c.build("parallel_connect_checks.cl", tech.defines)


_STUDENT = "bdpt_parallel_connect.cl"


def _student(c):
    return (Path(c.folder) / _STUDENT).read_text()


def _variant(c, name, text):
    """A folder beside the submission's with the grader's kernel and this bdpt_parallel_connect.cl (made once)."""
    directory = Path(c.folder) / name
    if not directory.is_dir():
        directory.mkdir()
        shutil.copyfile(Path(c.folder) / "parallel_connect_checks.cl", directory / "parallel_connect_checks.cl")
        (directory / _STUDENT).write_text(text)
    return directory


def _toolkit_part(text, start):
    """The definition in `text` that starts with `start`, up to its closing brace at the line start."""
    begin = text.index(start)
    return text[begin:text.index("\n}\n", begin) + 3]


_PARTS = {"find_sample": "HELPER int find_sample(", "bdpt_parallel_connect_count": "__kernel void bdpt_parallel_connect_count("}


def _with_reference_parts(c, student):
    """The student's file with their count kernel and find_sample renamed (kept, unused) and the
    toolkit's defined first, under their names: the `image` check then grades the rest of their
    file (the local index and the connection kernel), not again the bugs that `count` and
    `search` report. The student's lines keep their numbers (#line)."""
    toolkit = c.toolkit_source(_STUDENT)
    parts = []
    for name, start in _PARTS.items():
        student, found = re.subn(rf"\b{name}(\s*\([^()]*\)\s*\{{)", rf"student_{name}\1", student, count=1)
        if found:
            parts.append(_toolkit_part(toolkit, start))
    return ('#line 1 "toolkit bdpt_parallel_connect.cl"\n#include "bdpt_walk.h"\n' + "".join(parts)
            + f'#line 1 "{_STUDENT}"\n' + student)


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


@ASSIGNMENT.check("count", 20, "bdpt_parallel_connect_count: connections of each terminated sample, 0 otherwise",
                  "only a terminated sample has connections; count every strategy (s, t) that can make a path, "
                  "which is not every pair of vertex counts")
def _check_count(c):
    tech, _ = _parallel_connect(c)
    rng = c.rng(6)
    n = 500
    slots = BDPT_SLOT.zeros(n)
    slots["live"] = rng.integers(-1, 3, n)
    slots["light_vertices"] = rng.integers(1, 9, n)
    slots["eye_vertices"] = rng.integers(2, 9, n)
    counts = c.buffer(np.full(program.padded(n), -1, np.int32))
    program.launch(c.queue, tech.kernels.kernel("bdpt_parallel_connect_count"), n, np.int32(n), c.buffer(slots), counts)
    got = c.read(counts, np.int32, n)
    expected = np.where(slots["live"] == 0, (slots["light_vertices"] + 1) * slots["eye_vertices"] - 1, 0)
    wrong = np.flatnonzero(got != expected)
    if len(wrong):
        i = wrong[0]
        raise CheckFailed(f"slot {i} (live {slots['live'][i]}, {slots['light_vertices'][i]} light and "
                          f"{slots['eye_vertices'][i]} eye vertices) has {got[i]} connections, expected {expected[i]}")


@ASSIGNMENT.check("search", 20, "find_sample for every connection, random counts with zeros",
                  "keep an invariant (firsts[lo] <= g, the answer in [lo, hi)) and shrink the range until one slot "
                  "is left; samples with no connection share their first index with the next one")
def _check_search(c):
    rng = c.rng(7)
    for n in (300, 1000):
        counts = np.where(rng.random(n) < 0.3, 0, rng.integers(1, 40, n))
        problem = _search_problem(c, counts, f"{n} samples: ")
        if problem:
            raise CheckFailed(problem)


@ASSIGNMENT.check("search_edges", 15, "find_sample: one sample holds every connection, a pool of one, all ones",
                  "the range must include both ends: the first and the last sample can hold connections too")
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


# The grader's kernel of the `logarithmic` check, built after the instrumented file: each
# work-item reports how many rounds the loops of its find_sample made.
_ROUNDS_KERNEL = """
__kernel void grade_search_rounds(__global const int* firsts, const int n, const int total, __global int* found,
                                  __global int* rounds)
{
    int g = get_global_id(0), mine = 0;
    if (g >= total) return;
    found[g] = grade_counted_find_sample(firsts, n, g, &mine);
    rounds[g] = mine;
}
"""


@ASSIGNMENT.check("logarithmic", 10, "find_sample is a binary search: its loops go round at most 2 log2(n) + 2 "
                                     "times", "halve the range at every step: n samples take log2(n) steps, where "
                  "walking the samples one by one takes up to n")
def _check_logarithmic(c):
    """Count the rounds of find_sample's loops per connection (instrument.counted_copy)."""
    tech, _ = _parallel_connect(c)
    includes, code, defines = instrument.preprocessed(_student(c), tech.defines)
    counted = instrument.counted_copy(code, "find_sample", "find_sample")
    folder = _variant(c, "counted_search", instrument.assemble(includes, code, defines, counted, _ROUNDS_KERNEL))
    built = program.build(c.queue, "parallel_connect_checks.cl", tech.defines, directory=c.sources(folder))
    n = 1024
    counts = c.rng(10).integers(0, 8, n).astype(np.int32)
    firsts = (np.cumsum(counts) - counts).astype(np.int32)
    total = int(counts.sum())
    found, rounds = c.buffer(np.full(total, -1, np.int32)), c.buffer(np.zeros(total, np.int32))
    program.launch(c.queue, program.kernel(built, "grade_search_rounds"), total, c.buffer(firsts), np.int32(n),
                   np.int32(total), found, rounds)
    expected = np.searchsorted(firsts, np.arange(total), side="right") - 1
    if np.mean(c.read(found, np.int32, total) == expected) < 0.5:
        raise CheckFailed("find_sample is wrong for most connections: this check counts the steps of a search "
                          "that finds the samples (see `search`)")
    got = c.read(rounds, np.int32, total)
    limit = 2 * int(np.ceil(np.log2(n))) + 2
    worst = int(np.argmax(got))
    if got[worst] > limit:
        raise CheckFailed(f"the loops of find_sample go round {got[worst]} times for connection {worst} of {total} "
                          f"({n} samples; {int((got > limit).sum())} connections over {limit}): a binary search "
                          f"takes log2({n}) = {int(np.log2(n))} steps")


@ASSIGNMENT.check("image", 35, "bdpt_parallel_connect with your kernel (and the toolkit's count and find_sample): "
                               "the image of bdpt_naive_connect", "each connection's local index within its "
                  "sample picks its strategy (s, t): every strategy of every sample, once", hidden=True)
def _check_parallel_image(c):
    folder = _variant(c, "reference_parts", _with_reference_parts(c, _student(c)))
    image = c.technique(BdptParallelConnect, folder=folder).render(16, 16, 4, seed=c.seed(3)).image()
    expected = c.technique(BdptNaiveConnect, student=False).render(16, 16, 4, seed=c.seed(3)).image()
    same_image(image, expected, "bdpt_naive_connect's", rtol=1e-4, atol=1e-6)
