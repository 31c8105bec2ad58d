"""Host traffic of the path-tracing streams (issue 14, item 3; issue 48, item 2): with the SIMD
counters off, the host never waits for a count. Every kernel of a step is launched over the whole
stream and the counts stay on the device; the host reads a step's counts without blocking, once
every `reads_every` steps, and learns that the pass is over from a read queued `reads_every` steps
before (toolkit/techniques/pass_end.py). No iteration allocates; the buffers a render needs are
made once, at its start, and reused by every pass.

The hook wraps pyopencl.enqueue_copy (device -> host reads, blocking or not), pyopencl.Buffer
(allocations) and toolkit.opencl.program.launch (to split the render into iterations at its
extension kernel)."""
import numpy as np
import pyopencl as cl
import pytest

from toolkit.core.layout import PT_STEP
from toolkit.opencl import program
from toolkit.opencl.device import get_queue
from toolkit.opencl.device_scene import DeviceScene
from toolkit.techniques import PtCompactRegen, PtInplaceRegen, get_technique
from toolkit.techniques.pass_end import LAG

# The kernel that starts each iteration (one extension step over the stream; in place, the
# regeneration runs at its start).
EXTEND = {"pt_inplace_regen": "pt_inplace_regen_trace", "pt_compact_regen": "pt_compact_regen_trace",
          "pt_compact_regen/multipass": "extend_in_place_trace"}
# What a look at the counts reads: in place, the "any path alive" flag; compaction, the step's
# counts (PtStep: its length, survivors, shadow rays, next sample).
READ_BYTES = {"pt_inplace_regen": 4, "pt_compact_regen": PT_STEP.dtype.itemsize,
              "pt_compact_regen/multipass": PT_STEP.dtype.itemsize}
READS_EVERY = {"pt_inplace_regen": PtInplaceRegen.reads_every, "pt_compact_regen": PtCompactRegen.reads_every,
               "pt_compact_regen/multipass": PtCompactRegen.reads_every}


class Traffic:
    """Records, in order, ("read", bytes) or ("blocking read", bytes), ("alloc", bytes) and
    ("launch", kernel name)."""

    def __init__(self, monkeypatch):
        self.events = []
        real_copy, real_buffer, real_launch = cl.enqueue_copy, cl.Buffer, program.launch

        def enqueue_copy(queue, dest, src, **kwargs):
            if isinstance(src, cl.MemoryObjectHolder) and not isinstance(dest, cl.MemoryObjectHolder):
                kind = "blocking read" if kwargs.get("is_blocking", True) else "read"
                self.events.append((kind, int(kwargs.get("byte_count") or np.asarray(dest).nbytes)))
            return real_copy(queue, dest, src, **kwargs)

        def buffer(context, flags, size=0, hostbuf=None):
            self.events.append(("alloc", int(size or np.asarray(hostbuf).nbytes)))
            return real_buffer(context, flags, size, hostbuf)

        def launch(queue, kernel, n, *args, **kwargs):
            self.events.append(("launch", kernel.function_name))
            return real_launch(queue, kernel, n, *args, **kwargs)

        monkeypatch.setattr(cl, "enqueue_copy", enqueue_copy)
        monkeypatch.setattr(cl, "Buffer", buffer)
        monkeypatch.setattr(program, "launch", launch)

    def passes(self):
        """The events of each pass (render_traffic marks where each starts)."""
        starts = [i for i, (kind, _) in enumerate(self.events) if kind == "pass"] + [len(self.events)]
        return [self.events[a + 1:b] for a, b in zip(starts, starts[1:])]

    def iterations(self, extend):
        """The events of each whole iteration of every pass: from one extension launch up to the
        next one of the same pass."""
        whole = []
        for events in self.passes():
            starts = [i for i, (kind, what) in enumerate(events) if kind == "launch" and what == extend]
            whole += [events[a:b] for a, b in zip(starts, starts[1:])]
        return whole


def summary(events):
    reads = [size for kind, size in events if kind.endswith("read")]
    allocs = [size for kind, size in events if kind == "alloc"]
    return {"read_bytes": sum(reads), "reads": len(reads), "allocs": len(allocs),
            "blocking_reads": sum(kind == "blocking read" for kind, _ in events)}


def render_traffic(monkeypatch, scene, technique, stream_size, resolution=(32, 16), spp=4, passes=2,
                   count_simd=False, with_technique=False):
    """The traffic of one render of `passes` equal passes, at `stream_size` (counters off); with
    `with_technique`, (the technique, the traffic)."""
    cls, options = get_technique(technique)
    queue = get_queue()
    tech = cls(queue, DeviceScene(queue, scene), count_simd=count_simd, **options)
    tech.stream_size = stream_size
    tech.target_batch = resolution[0] * resolution[1] * spp // passes
    with monkeypatch.context() as patch:
        traffic = Traffic(patch)
        run_pass = tech.run_pass

        def marked(*args):
            traffic.events.append(("pass", None))
            return run_pass(*args)
        patch.setattr(tech, "run_pass", marked)
        film = tech.render(*resolution, spp, seed=3)
    assert int(film.count.min()) == int(film.count.max()) == spp
    return (tech, traffic) if with_technique else traffic


@pytest.mark.parametrize("technique", sorted(EXTEND))
def test_the_host_never_waits_for_a_count_and_an_iteration_allocates_nothing(monkeypatch, cornell_box, technique):
    per_render = {}
    every = READS_EVERY[technique]
    for stream_size in (256, 1024):
        traffic = render_traffic(monkeypatch, cornell_box, technique, stream_size)
        iterations = [summary(events) for events in traffic.iterations(EXTEND[technique])]
        assert len(iterations) > 4 * every
        # No blocking read in the whole render (the film's sums are read behind the next pass too).
        assert summary(traffic.events)["blocking_reads"] == 0
        # Every iteration: no allocation, at most one read, of the counts' few bytes.
        assert all(it["allocs"] == 0 and it["reads"] <= 1 and it["read_bytes"] == it["reads"] * READ_BYTES[technique]
                   for it in iterations), iterations
        # One read per `every` iterations at most: iterations between reads run without the host.
        reads = sum(it["reads"] for it in iterations)
        assert 0 < reads <= len(iterations) / every + len(traffic.passes()), (reads, len(iterations))
        per_render[stream_size] = summary(traffic.events)["allocs"]
    print(f"{technique}: {READ_BYTES[technique]} bytes read every {every} iteration(s), never waited for; "
          f"buffers allocated per render {per_render[256]}")
    # The render's buffers: a fixed small number, made in the first pass only (with the film's
    # two on the device, toolkit/opencl/device_film.py).
    assert per_render[256] == per_render[1024] <= 18


@pytest.mark.parametrize("technique", sorted(EXTEND))
def test_the_host_learns_the_end_of_a_pass_a_few_steps_late(monkeypatch, cornell_box, technique):
    """The host learns of a pass's end from a read LAG steps old, made once every `every` steps: it
    queues a few steps more, which find no work (the images are the same: tests/snapshot_images.py).
    The SIMD counters, summed on the device, count the steps that had work (each numbered extension
    step) and change no step: a counted render launches what an uncounted one does."""
    every = READS_EVERY[technique]
    steps, tech = {}, {}
    for count_simd in (True, False):
        tech[count_simd], traffic = render_traffic(monkeypatch, cornell_box, technique, 256, passes=1,
                                                   count_simd=count_simd, with_technique=True)
        steps[count_simd] = sum(kind == "launch" and what == EXTEND[technique] for kind, what in traffic.events)
    worked = sum(it["phase"] == "extend" for it in tech[True].recorder.simd.per_iteration)
    assert steps[True] == steps[False]
    assert worked < steps[False] <= worked + every + LAG, (worked, steps)


@pytest.mark.parametrize("technique", sorted(EXTEND))
def test_later_passes_reuse_the_first_pass_buffers(monkeypatch, cornell_box, technique):
    passes = render_traffic(monkeypatch, cornell_box, technique, 256, passes=4).passes()
    assert len(passes) == 4
    assert [summary(events)["allocs"] for events in passes[1:]] == [0, 0, 0]


def test_a_compactor_keeps_its_scratch_memory(monkeypatch, queue):
    """After reserve(n), compacting and scanning streams of up to n items into buffers of the
    caller's allocates nothing: a technique that compacts every iteration allocates once."""
    from toolkit.opencl.compaction import Compactor
    compactor = Compactor(queue)
    n = 5000
    flags = cl.Buffer(queue.context, cl.mem_flags.READ_WRITE | cl.mem_flags.COPY_HOST_PTR,
                      hostbuf=(np.arange(n) % 3 == 0).astype(np.int32))
    out = cl.Buffer(queue.context, cl.mem_flags.READ_WRITE, 4 * n)
    compactor.reserve(n)
    with monkeypatch.context() as patch:
        traffic = Traffic(patch)
        for length in (n, 1, 777, n):
            for method in ("immediate", "multipass"):
                assert compactor.compact_indices(flags, length, method, out=out)[1] == len(range(0, length, 3))
            assert compactor.exclusive_scan(flags, length, out=out)[1] == len(range(0, length, 3))
    assert summary(traffic.events)["allocs"] == 0


@pytest.mark.parametrize("technique", ["bdpt_naive_connect", "bdpt_parallel_connect"])
def test_a_bdpt_walk_step_never_waits_for_a_count(monkeypatch, cornell_box, technique):
    """BDPT's walk keeps its streams' lengths on the device and reads its counters behind the walk
    (bdpt_evaluator.py): between two walk steps the host waits for nothing, unless a connect
    phase came between them (it waits for the terminated slots and the streams' lengths)."""
    cls, options = get_technique(technique)
    queue = get_queue()
    tech = cls(queue, DeviceScene(queue, cornell_box), count_simd=False, pool_size=128, **options)
    with monkeypatch.context() as patch:
        traffic = Traffic(patch)
        film = tech.render(16, 16, 4, seed=3)
    assert int(film.count.min()) == int(film.count.max()) == 4
    steps, current = [], []
    extends = 0
    for kind, what in traffic.events:
        if kind == "launch" and what == "bdpt_extend":
            if extends % 2 == 0:           # a step begins with the eye stream's launch, the light's follows
                steps.append(current)
                current = []
            extends += 1
        current.append((kind, what))
    walking = [s for s in steps if ("launch", "bdpt_mark_terminated") not in s]
    connecting = len(steps) - len(walking)
    assert len(walking) > 10 and connecting >= 2     # a pool of 128: several connect phases
    assert all(summary(s)["blocking_reads"] == 0 for s in walking)
    # Each walk step queues one read of the counters (20 bytes), not waited for at once.
    assert all(summary(s)["reads"] <= 1 for s in walking)
