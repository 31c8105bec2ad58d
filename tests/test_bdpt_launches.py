"""BDPT's host cost (issue 48): what the host queues per walk step and per connect phase, and the
listing kernels that replaced the Compactor's scan and compaction (cl/bdpt_walk.h), against numpy."""
import numpy as np
import pyopencl as cl
import pytest

from toolkit.core.layout import BDPT_SLOT, ListingInt, SlotState, WalkCounter
from toolkit.opencl import program
from toolkit.opencl.device_scene import DeviceScene
from toolkit.techniques import BdptNaiveConnect, BdptParallelConnect

# What a listing launches: the connect phase's count kernel, then the walk's three listing kernels.
LISTING = ("bdpt_mark_terminated", "bdpt_list_offsets", "bdpt_list_terminated")


def queued(monkeypatch, tech, width, height, spp):
    """Everything a render queues, in order: ("launch", kernel), ("fill", bytes), ("copy", "read" or
    "device"), ("alloc", bytes), and ("pass", None) where each pass starts."""
    events = []
    real_launch, real_fill, real_copy, real_buffer = program.launch, cl.enqueue_fill_buffer, cl.enqueue_copy, cl.Buffer

    def launch(queue, kernel, n, *args, **kwargs):
        events.append(("launch", kernel.function_name))
        return real_launch(queue, kernel, n, *args, **kwargs)

    def fill(queue, buffer, pattern, offset, size, *args, **kwargs):
        events.append(("fill", size))
        return real_fill(queue, buffer, pattern, offset, size, *args, **kwargs)

    def copy(queue, dest, src, **kwargs):
        events.append(("copy", "device" if isinstance(dest, cl.MemoryObjectHolder) else "read"))
        return real_copy(queue, dest, src, **kwargs)

    def buffer(context, flags, size=0, hostbuf=None):
        events.append(("alloc", size))
        return real_buffer(context, flags, size, hostbuf)

    run_pass = tech.run_pass

    def marked(*args):
        events.append(("pass", None))
        return run_pass(*args)
    with monkeypatch.context() as patch:
        for module, name, wrapper in ((program, "launch", launch), (cl, "enqueue_fill_buffer", fill),
                                      (cl, "enqueue_copy", copy), (cl, "Buffer", buffer)):
            patch.setattr(module, name, wrapper)
        patch.setattr(tech, "run_pass", marked)
        tech.render(width, height, spp, seed=3)
    return events


@pytest.mark.parametrize("cls", [BdptNaiveConnect, BdptParallelConnect])
def test_a_walk_step_is_a_launch_per_stream_and_a_pass_clears_copies_and_allocates_nothing(monkeypatch, queue, cornell_box, cls):
    """Inside a pass after the first (whose records may first outgrow their buffers), the host queues
    per walk step two launches (eye, light), per listing four and one read (not waited for), per connect phase
    its kernel and the film's, per regeneration two: no fill, no copy on the device, no
    buffer made."""
    tech = cls(queue, DeviceScene(queue, cornell_box), count_simd=False, pool_size=128)
    tech.target_batch = 16 * 16 * 2        # 16x16 at 6 spp: three passes of 2 spp
    events = queued(monkeypatch, tech, 16, 16, 6)
    starts = [i for i, (kind, _) in enumerate(events) if kind == "pass"]
    assert len(starts) == 3
    pass_events = events[starts[1] + 1:starts[2]]
    assert not [e for e in pass_events if e[0] == "alloc" or e == ("copy", "device")]
    # the one fill: start_pass clears the walk's counters (WalkCounter.COUNTER_INTS ints)
    assert [e for e in pass_events if e[0] == "fill"] == [("fill", 4 * WalkCounter.COUNTER_INTS)]
    steps, current = [], []
    extends = 0
    for event in pass_events:
        if event == ("launch", "bdpt_extend"):
            if extends % 2 == 0:           # a step begins with the eye stream's launch, the light's follows
                steps.append(current)
                current = []
            extends += 1
        current.append(event)
    steps = steps[1:] + [current]          # each from its walk launch to the next
    connect = cls.connect_phase(tech).count_kernel
    listings = 0
    for step in steps:
        launches = [what for kind, what in step if kind == "launch"]
        assert launches[:2] == ["bdpt_extend"] * 2 and launches.count("bdpt_extend") == 2   # eye, then light
        rest = launches[2:]
        if connect in rest:                # a listing: four launches and the read of its counts
            at = rest.index(connect)
            assert tuple(rest[at + 1:at + 4]) == LISTING
            del rest[at:at + 4]
            listings += 1
        # the pass's end: its image resolved on the device, and added to the film there (a device
        # with float64) or read, one pass behind
        assert set(rest) <= {tech.source.removesuffix(".cl"), "record_film_add", "bdpt_regenerate",
                             "record_film_resolve", "film_accumulate_pass"}, rest
        image_read = "record_film_resolve" in rest and "film_accumulate_pass" not in rest
        assert sum(e == ("copy", "read") for e in step) == (connect in launches) + image_read
    assert listings >= 2


def test_the_listing_kernels_mark_scan_and_list_like_numpy(queue, cornell_box):
    """bdpt_mark_terminated, bdpt_list_offsets and bdpt_list_terminated on random slots (a pool of
    10,000: not a whole number of work-groups, and more groups than one work-item's run of them):
    with enough terminated samples, the terminated slots become SLOT_CONNECTING, firsts is the
    exclusive scan of their records (0 for the others), the list is their slots in order, the
    listing holds their count, their records and the streams' lengths, and they no longer count as
    terminated; with too few, nothing changes but the scan of nothing. The listing also holds the
    walk's steps so far."""
    tech = BdptParallelConnect(queue, DeviceScene(queue, cornell_box), count_simd=False, pool_size=64)
    k, mem = tech.kernels, tech.memory
    rng = np.random.default_rng(48)
    pool = 10_000
    slots = BDPT_SLOT.zeros(pool)
    slots["live"] = rng.choice([SlotState.IDLE, SlotState.TERMINATED, 1, 2], pool)
    terminated = slots["live"] == SlotState.TERMINATED
    counts = rng.integers(0, 50, pool).astype(np.int32)
    blocks = mem.padded(pool) // k.local_size
    for threshold, listed in ((int(terminated.sum()), True), (int(terminated.sum()) + 1, False)):
        counters = np.zeros(WalkCounter.COUNTER_INTS, np.int32)
        counters[WalkCounter.TERMINATED_SAMPLES] = terminated.sum()
        counters[WalkCounter.LENGTH_RING + 2 * 2:][:2] = (123, 45)      # pair 2 of the ring
        counters[WalkCounter.WALK_STEPS] = 17
        rw, copy = cl.mem_flags.READ_WRITE, cl.mem_flags.COPY_HOST_PTR
        d_slots, d_counts, d_counters = (cl.Buffer(queue.context, rw | copy, hostbuf=a) for a in (slots, counts, counters))
        block_sums, firsts, listed_slots, listing = (mem.int_buffer(n) for n in (2 * blocks, pool, pool, ListingInt.INTS))
        k.launch("bdpt_mark_terminated", pool, np.int32(pool), np.int32(threshold), d_counters, d_slots, d_counts, block_sums)
        k.launch("bdpt_list_offsets", 1, np.int32(blocks), np.int32(2), d_counters, block_sums, listing)
        k.launch("bdpt_list_terminated", pool, np.int32(pool), d_slots, d_counts, block_sums, firsts, listed_slots)
        got_slots = mem.read_structs(BDPT_SLOT, d_slots, pool)
        got_counters, got_listing = mem.read_ints(d_counters, WalkCounter.COUNTER_INTS), mem.read_ints(listing, ListingInt.INTS)
        got_firsts = mem.read_ints(firsts, pool)
        marked = terminated if listed else np.zeros(pool, bool)
        kept = np.where(marked, counts, 0)
        expected_live = np.where(marked, SlotState.CONNECTING, slots["live"])
        assert np.array_equal(got_slots["live"], expected_live)
        assert np.array_equal(got_firsts, np.cumsum(kept) - kept)
        assert got_listing.tolist() == [marked.sum(), kept.sum(), 123, 45, 17]
        assert got_counters[WalkCounter.TERMINATED_SAMPLES] == terminated.sum() - marked.sum()
        assert np.array_equal(mem.read_ints(listed_slots, pool)[:marked.sum()], np.flatnonzero(marked))
