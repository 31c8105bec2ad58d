"""Host traffic of the path-tracing streams (issue 14, item 3): with the SIMD counters off, one
iteration (an extension step with its regeneration and compaction) reads back a few bytes of
counters and allocates nothing, whatever the stream size; the buffers a render needs are made
once, at its start, and reused by every pass.

The hook wraps pyopencl.enqueue_copy (device -> host reads), pyopencl.Buffer (allocations) and
toolkit.opencl.program.launch (to split the render into iterations at its extension kernel)."""
import numpy as np
import pyopencl as cl
import pytest

from toolkit.opencl import program
from toolkit.opencl.device import get_queue
from toolkit.opencl.device_scene import DeviceScene
from toolkit.techniques import PtInplaceRegen, get_technique

# The kernel that starts each iteration (one extension step over the stream).
EXTEND = {"pt_inplace_regen": "extend_in_place_trace", "pt_compact_regen": "pt_compact_regen_trace",
          "pt_compact_regen/multipass": "extend_in_place_trace"}
# What an iteration reads back: in place, the "any path alive" flag, once every
# PtInplaceRegen.reads_every iterations; immediate compaction, the two stream lengths
# (StreamCounter), every iteration (they size the next launches); multi-pass compaction, the
# survivors' count.
READ_BYTES = {"pt_inplace_regen": 4, "pt_compact_regen": 8, "pt_compact_regen/multipass": 4}
READS_EVERY = {"pt_inplace_regen": PtInplaceRegen.reads_every, "pt_compact_regen": 1, "pt_compact_regen/multipass": 1}


class Traffic:
    """Records, in order, ("read", bytes), ("alloc", bytes) and ("launch", kernel name)."""

    def __init__(self, monkeypatch):
        self.events = []
        real_copy, real_buffer, real_launch = cl.enqueue_copy, cl.Buffer, program.launch

        def enqueue_copy(queue, dest, src, **kwargs):
            if isinstance(src, cl.MemoryObjectHolder) and not isinstance(dest, cl.MemoryObjectHolder):
                self.events.append(("read", int(kwargs.get("byte_count") or np.asarray(dest).nbytes)))
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
    reads = [size for kind, size in events if kind == "read"]
    allocs = [size for kind, size in events if kind == "alloc"]
    return {"read_bytes": sum(reads), "reads": len(reads), "allocs": len(allocs)}


def render_traffic(monkeypatch, scene, technique, stream_size, resolution=(32, 16), spp=4, passes=2):
    """The traffic of one render of `passes` equal passes, at `stream_size` (counters off)."""
    cls, options = get_technique(technique)
    queue = get_queue()
    tech = cls(queue, DeviceScene(queue, scene), count_simd=False, **options)
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
    return traffic


@pytest.mark.parametrize("technique", sorted(EXTEND))
def test_an_iteration_reads_a_few_counter_bytes_and_allocates_nothing(monkeypatch, cornell_box, technique):
    per_render = {}
    every = READS_EVERY[technique]
    for stream_size in (256, 1024):
        traffic = render_traffic(monkeypatch, cornell_box, technique, stream_size)
        iterations = [summary(events) for events in traffic.iterations(EXTEND[technique])]
        assert len(iterations) > 4 * every
        # Every iteration: no allocation, at most one read, of the counters' few bytes.
        assert all(it["allocs"] == 0 and it["reads"] <= 1 and it["read_bytes"] == it["reads"] * READ_BYTES[technique]
                   for it in iterations), iterations
        # One read per `every` iterations: iterations between reads run without waiting for the host.
        reads = sum(it["reads"] for it in iterations)
        assert abs(reads - len(iterations) / every) <= len(traffic.passes()), (reads, len(iterations))
        per_render[stream_size] = summary(traffic.events)["allocs"]
    print(f"{technique}: {READ_BYTES[technique]} bytes read every {every} iteration(s); "
          f"buffers allocated per render {per_render[256]}")
    # The render's buffers: a fixed small number, made in the first pass only.
    assert per_render[256] == per_render[1024] <= 16


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
