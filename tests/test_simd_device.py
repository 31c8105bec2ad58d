"""The SIMD counters summed on the device (toolkit/opencl/simd_counters.py, cl/simd_counters.cl)
give the figures that the host's sums of every step's lanes give (toolkit/core/simd.py's
PhaseCounter, fed lane by lane: SimdRecorder's per-step mode, the counting as it was before the
step log): the same integers, so the same efficiencies, per phase and per iteration, bit for bit.
Each technique renders a small image twice with one seed, once each way, at stream and pool sizes
small enough that a pass takes many steps, connect phases and drains."""
import numpy as np
import pytest

from toolkit.core.layout import SimdSum
from toolkit.core.simd import PhaseCounter
from toolkit.opencl.device_scene import DeviceScene
from toolkit.opencl.traffic import Traffic
from toolkit.techniques import get_technique

SIZES = {"pt_inplace_regen": {"stream_size": 512}, "pt_compact_regen": {"stream_size": 512},
         "pt_compact_regen/multipass": {"stream_size": 512}, "bdpt_naive_connect": {"pool_size": 256},
         "bdpt_parallel_connect": {"pool_size": 256}, "mlt": {"chains": 256, "pool_size": 256, "candidates": 2}}
TECHNIQUES = ["pt_naive", *SIZES]


def counted(queue, scene, technique, spp=2, size=16, count_simd=True, check=True):
    """A render with its counters summed on the device and every step counted a second time as
    before (SimdRecorder.check_against_host): (the technique, its image, the host's traffic)."""
    cls, options = get_technique(technique)
    tech = cls(queue, DeviceScene(queue, scene), count_simd=count_simd, **options, **SIZES.get(technique, {}))
    if count_simd and check:
        tech.recorder.check_against_host()
    with Traffic() as traffic:
        film = tech.render(size, size, spp, seed=7)
    return tech, film.image(), traffic.figures()


def figures(recorder):
    return {"simd": (recorder.simd.active, recorder.simd.issued), "per_iteration": recorder.simd.per_iteration,
            "traversal": (recorder.traversal.active, recorder.traversal.issued), "iterations": recorder.iterations,
            "others": {name: (recorder.counter(name).active, recorder.counter(name).issued)
                       for name in ("walk_without_compaction", "connect_terminated_packed")}}


@pytest.mark.parametrize("technique", TECHNIQUES)
def test_the_device_sums_are_the_hosts(queue, cornell_box, technique):
    """Every step counted both ways in one render (a stream's order of paths differs from run to run
    where compaction takes one atomic per work-group, and with it the warps)."""
    tech, image, _ = counted(queue, cornell_box, technique)
    on_device, on_host = figures(tech.recorder), figures(tech.recorder.reference)
    for key in on_host:
        assert on_device[key] == on_host[key], key
    assert on_device["per_iteration"] and on_device["simd"][0]          # something was counted
    if tech.family == "bdpt":
        assert on_device["others"]["walk_without_compaction"][0]
    if technique == "bdpt_naive_connect":
        assert on_device["others"]["connect_terminated_packed"][0]


@pytest.mark.parametrize("technique,warp_width", [("bdpt_parallel_connect", 32), ("mlt", 16),
                                                   ("bdpt_naive_connect", 128)])
def test_the_walk_counts_its_own_lanes(queue, cornell_box, technique, warp_width, monkeypatch):
    """A counted BDPT walk step adds its lanes to the step log inside bdpt_extend (cl/simd_counters.h
    simd_count_group): no counting launch of its own, where a warp fits in a work-group (local size
    64); wider warps (128) are counted by simd_count_two_steps as before. The host's figures either way."""
    from toolkit.opencl import program
    launched = []
    real = program.launch
    monkeypatch.setattr(program, "launch", lambda queue, kernel, *a, **k: (launched.append(kernel.function_name),
                                                                           real(queue, kernel, *a, **k))[1])
    cls, options = get_technique(technique)
    tech = cls(queue, DeviceScene(queue, cornell_box), count_simd=True, warp_width=warp_width, **options,
               **SIZES[technique])
    tech.recorder.check_against_host()
    tech.render(16, 16, 2, seed=7)
    assert figures(tech.recorder) == figures(tech.recorder.reference)
    walk_steps = tech.recorder.simd.per_iteration
    assert sum(entry["phase"] == "walk" for entry in walk_steps) > 20
    assert ("simd_count_two_steps" in launched) == (program.LOCAL_SIZE % warp_width != 0)


@pytest.mark.parametrize("technique", ["pt_inplace_regen", "bdpt_naive_connect"])
def test_a_full_log_is_read_and_counting_goes_on(queue, cornell_box, technique, monkeypatch):
    """A log of 5 rows and 2 histograms fills many times a render: each time it is read, the steps
    so far replayed, and the next steps counted into the emptied log, with the same figures."""
    from toolkit.opencl import simd_counters
    monkeypatch.setattr(simd_counters, "ROWS", 5)
    monkeypatch.setattr(simd_counters, "HISTOGRAM_ROWS", 2)
    tech, _, _ = counted(queue, cornell_box, technique)
    assert figures(tech.recorder) == figures(tech.recorder.reference)
    assert len(tech.recorder.simd.per_iteration) > 3 * 5


@pytest.mark.parametrize("technique", ["pt_compact_regen", "bdpt_naive_connect"])
def test_counting_on_the_device_changes_nothing_else(queue, cornell_box, technique):
    """The counters only watch: the image is the one rendered without them (so are the steps), and
    no read waits for a step's lanes while the render runs (the log is read when looked at)."""
    _, image, traffic = counted(queue, cornell_box, technique, check=False)
    _, uncounted, uncounted_traffic = counted(queue, cornell_box, technique, count_simd=False)
    np.testing.assert_array_equal(image, uncounted)
    assert (traffic["reads"], traffic["blocking_reads"]) == (uncounted_traffic["reads"],
                                                             uncounted_traffic["blocking_reads"])


@pytest.mark.parametrize("technique", ["pt_inplace_regen", "pt_compact_regen", "pt_compact_regen/multipass"])
def test_steps_counted_in_rounds_across_passes(queue, cornell_box, technique, monkeypatch):
    """A path tracer's steps are counted several to a launch, its step kernels writing to buffers in
    turn: pt_inplace_regen's a round of 8 (StepTurns), pt_compact_regen's two (StepPairs). Five
    passes of one sample per pixel, each ending after a number of steps that fills no whole round
    (the steps held at a pass's end are counted then). Every step handed over is replayed once,
    with the host's figures, and the image is the uncounted one."""
    from toolkit.techniques.simd_recorder import StepPairs, StepTurns
    handed, replayed = [0], [0]
    holder, method = (StepTurns, "add") if technique == "pt_inplace_regen" else (StepPairs, "lanes")
    real = getattr(holder, method)

    def hand_over(self, replay, **step):
        handed[0] += 1

        def counted_replay(recorder, sums):
            replayed[0] += recorder is self.recorder    # the device's recorder (its reference replays too)
            return replay(recorder, sums)
        return real(self, counted_replay, **step)
    monkeypatch.setattr(holder, method, hand_over)
    cls, options = get_technique(technique)
    counted_tech = cls(queue, DeviceScene(queue, cornell_box), count_simd=True, pass_spp=1, **options,
                       **SIZES[technique])
    counted_tech.recorder.check_against_host()
    image = counted_tech.render(16, 16, 5, seed=3).image()
    plain = cls(queue, DeviceScene(queue, cornell_box), count_simd=False, pass_spp=1, **options, **SIZES[technique])
    np.testing.assert_array_equal(image, plain.render(16, 16, 5, seed=3).image())
    on_device = figures(counted_tech.recorder)
    assert on_device == figures(counted_tech.recorder.reference)
    assert len(on_device["per_iteration"]) > 5 * 5
    assert replayed[0] == handed[0] > 5 * 5


def test_pt_inplace_regen_drains_when_its_sample_counter_says_so(queue, cornell_box, monkeypatch):
    """The counters mark a step as the final drain from the samples its regenerations started, added
    up (PassCount.step); checked here against the sample counter itself, read by the host after each
    counted step's regeneration (a blocking read of next_sample: the steps' rounds are counted later,
    so the device's counter has moved on by then). One pass of 2,048 samples on 512 slots."""
    import pyopencl as cl
    from toolkit.techniques import pt_inplace_regen as module
    at_budget, passes = [], []
    real_count, real_pass = module.PtInplaceRegen.count_extend, module.PtInplaceRegen.run_pass

    def count_extend(self, counting, slots):
        value = np.zeros(1, np.int32)
        mem = self.memory.reused(("slots", slots), None)     # the pass's slot buffers, made already
        cl.enqueue_copy(self.queue, value, mem.next_sample)
        at_budget.append(int(value[0]) >= counting.budget)
        real_count(self, counting, slots)
    monkeypatch.setattr(module.PtInplaceRegen, "count_extend", count_extend)
    monkeypatch.setattr(module.PtInplaceRegen, "run_pass", lambda self, *a: (passes.append(a), real_pass(self, *a))[1])
    tech, _, _ = counted(queue, cornell_box, "pt_inplace_regen", size=32, check=False)
    assert len(passes) == 1
    # one "generate" entry per counted step, its regeneration; the steps queued after the pass's end
    # (before the host learned of it) are not counted
    steps = [entry["draining"] for entry in tech.recorder.simd.per_iteration if entry["phase"] == "generate"]
    assert len(steps) < len(at_budget) and any(steps) and not all(steps)
    assert steps == at_budget[:len(steps)]


def test_a_wide_sum_carries_into_its_high_word(queue):
    """The step log's sums are 64-bit integers of two 32-bit words: a loop of 2^31 + 2^31 lane-steps
    (two lanes past what one word holds) comes out exact."""
    from toolkit.core.layout import LANE_COUNTS
    from toolkit.opencl.simd_counters import StepLog
    import pyopencl as cl
    lanes = LANE_COUNTS.zeros(40)
    lanes["work"][:3] = 1
    lanes["closest_steps"][[0, 1, 39]] = [2 ** 31 - 1, 2 ** 31 - 1, 5]
    buffer = cl.Buffer(queue.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=lanes)
    log = StepLog(queue, warp_width=32)
    log.count(buffer, 4, 40)
    sums = log.read()[0]
    assert sums[SimdSum.CLOSEST_SUM] == 2 * (2 ** 31 - 1) + 5
    assert sums[SimdSum.CLOSEST_WARP_MAX] == 2 ** 31 - 1 + 5
    assert (sums[SimdSum.LANES], sums[SimdSum.WORK_LANES], sums[SimdSum.WORK_WARPS]) == (40, 3, 1)


@pytest.mark.parametrize("warp_width", [1, 4, 32, 100])
def test_packed_loops_against_numpy(queue, warp_width):
    """simd_count_packed (one work-group walking the lanes in chunks) against PhaseCounter's sums of
    the lanes with work packed side by side, over chunk and warp boundaries and a partial last warp."""
    from toolkit.core.layout import LANE_COUNTS
    from toolkit.opencl.simd_counters import StepLog
    import pyopencl as cl
    rng = np.random.default_rng(warp_width)
    lanes = LANE_COUNTS.zeros(1000)
    lanes["work"] = rng.integers(0, 9, 1000) * (rng.random(1000) < 0.3)
    buffer = cl.Buffer(queue.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=lanes)
    log = StepLog(queue, warp_width=warp_width)
    log.count(buffer, 4, 1000, packed=True)
    sums = log.read()[0]
    expected = PhaseCounter(warp_width)
    work = lanes["work"]
    expected.add_warp_loops("connect", work[work > 0])
    assert sums[SimdSum.WORK_SUM] == expected.active["connect"]
    assert sums[SimdSum.PACKED_WARP_MAX] * warp_width == expected.issued["connect"]
