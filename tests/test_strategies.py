"""The path-tracing strategies against each other, their sample accounting, and the SIMD
counters against the talk's figures."""
import gc
import json
import subprocess
import sys

import numpy as np
import pyopencl as cl
import pytest

import toolkit
from toolkit.verify.same_image import PT_FAMILY, SAME_DEVICE
from toolkit.core.simd import PhaseCounter
from toolkit.opencl.device import get_queue
from toolkit.opencl.device_model import is_gpu
from toolkit.techniques import TECHNIQUES, VARIANTS

PT = list(PT_FAMILY)


@pytest.mark.parametrize("scene_name", ["cornell_box", "cornell_spheres"])
def test_strategies_compute_the_same_samples(scene_name, request):
    """Random numbers are keyed by (seed, pixel, sample, dimension), not by work-item, so every
    schedule computes the same samples: the images agree to float rounding (queued shadow rays
    add their part in another order), far tighter than any statistical tolerance."""
    scene = request.getfixturevalue(scene_name)
    images = {t: toolkit.render(scene, technique=t, spp=8, seed=4, resolution=(32, 32)).image for t in PT}
    base = images["pt_naive"]
    for name, image in images.items():
        np.testing.assert_allclose(image, base, *SAME_DEVICE, err_msg=name)


@pytest.mark.parametrize("technique", [*TECHNIQUES, *VARIANTS])
def test_the_work_group_size_does_not_change_the_image(cornell_box, technique):
    """Every technique built and launched at local sizes 32, 64 and 256 (the kernels'
    reqd_work_group_size, local arrays and in-kernel compaction scans follow it) gives the same
    image, bit for bit: random numbers are keyed by sample, not by work-item, and every sample
    adds its parts in the same order whatever the work-groups."""
    from toolkit.opencl import program
    images = {}
    for size in (32, 64, 256):
        result = toolkit.render(cornell_box, technique=technique, spp=2, seed=5, resolution=(13, 7), local_size=size)
        assert result.stats["local_size"] == size
        assert result.stats["samples_per_pixel"] == [2, 2]
        images[size] = result.image
    for size in (32, 256):
        np.testing.assert_array_equal(images[size], images[64], err_msg=f"{technique} at local size {size}")
    # The build really took the size: a kernel with reqd_work_group_size(LOCAL_SIZE) reports it.
    if technique == "pt_compact_regen":
        from toolkit.api import as_scene
        from toolkit.opencl.device import get_queue
        from toolkit.opencl.device_scene import DeviceScene
        queue = get_queue()
        tech = TECHNIQUES[technique](queue, DeviceScene(queue, as_scene(cornell_box)), local_size=32)
        kernel = program.kernel(tech.kernels.program, "pt_compact_regen_shade")
        info = kernel.get_work_group_info(cl.kernel_work_group_info.COMPILE_WORK_GROUP_SIZE, queue.device)
        assert list(info) == [32, 1, 1]


@pytest.mark.parametrize("size", [0, 16, 48, 512, 64.0, True, "64"])
def test_a_bad_work_group_size_is_refused_before_any_work(cornell_box, size):
    from toolkit.opencl.compaction import Compactor
    from toolkit.opencl.device import get_queue
    from toolkit.core.validate import InputError
    with pytest.raises(InputError, match="local_size"):
        toolkit.render(cornell_box, technique="pt_naive", spp=1, resolution=(4, 4), local_size=size)
    with pytest.raises(InputError, match="local_size"):
        Compactor(get_queue(), local_size=size)
    with pytest.raises(InputError, match="unknown option 'local_size'"):   # render's argument, not an option
        toolkit.render(cornell_box, technique="pt_naive", spp=1, resolution=(4, 4), options={"local_size": 64})


@pytest.mark.parametrize("technique", PT)
@pytest.mark.parametrize("resolution, spp", [((7, 5), 3), ((64, 48), 5), ((200, 180), 2)])
def test_every_pixel_gets_exactly_its_samples(cornell_box, technique, resolution, spp):
    """Whatever the stream size (larger or smaller than the budget, not a multiple of the
    work-group), every pixel gets exactly spp samples; the film raises if a sample is lost."""
    result = toolkit.render(cornell_box, technique=technique, spp=spp, seed=1, resolution=resolution)
    assert result.stats["samples_per_pixel"] == [spp, spp]
    assert result.image.shape == (resolution[1], resolution[0], 3)


def test_counting_does_not_change_the_image(cornell_box):
    for t in PT:
        on = toolkit.render(cornell_box, technique=t, spp=4, seed=2, resolution=(32, 32), count_simd=True)
        off = toolkit.render(cornell_box, technique=t, spp=4, seed=2, resolution=(32, 32), count_simd=False)
        np.testing.assert_array_equal(on.image, off.image)
        assert off.stats["simd_efficiency"] == {}


def test_phase_counter_counts_hand_made_warps_exactly():
    c = PhaseCounter(warp_width=4)
    # Two warps: lanes (1,1,0,0) and (0,0,0,0): only the first warp issues -> 2 of 4.
    c.add_stream_step("extend", np.array([1, 1, 0, 0, 0, 0, 0, 0], bool))
    # A packed stream of 5 active lanes: 2 warps issued (8 lanes), 5 active.
    c.add_stream_step("generate", 5)
    # Loops of 3 and 1 iterations in one warp of 4 lanes: issued 4 * 3 = 12, active 3 + 1 = 4.
    c.add_warp_loops("shadow", [3, 1, 0, 0])
    eff = c.efficiency()
    assert eff["extend"] == pytest.approx(2 / 4)
    assert eff["generate"] == pytest.approx(5 / 8)
    assert eff["shadow"] == pytest.approx(4 / 12)
    assert eff["overall"] == pytest.approx((2 + 5 + 4) / (4 + 8 + 12))


def test_loop_iterations_per_iteration_by_hand_and_by_counting():
    """add_loop_iterations' per-iteration figures (counted from the lengths' histogram): a hand-made
    case, and a long random launch against counting lane by lane at each iteration."""
    c = PhaseCounter(warp_width=4)
    c.add_loop_iterations("connect", [3, 1, 0, 0, 0, 0, 0, 0], first_iteration=5)
    assert [(it["iteration"], it["active"], it["efficiency"]) for it in c.per_iteration] == \
        [(5, 2, 2 / 4), (6, 1, 1 / 4), (7, 1, 1 / 4)]
    x = np.random.default_rng(3).integers(0, 30, 10_000)
    c = PhaseCounter(warp_width=32)
    c.add_loop_iterations("extend", x)
    warp_longest = np.concatenate([x, np.zeros(-len(x) % 32, x.dtype)]).reshape(-1, 32).max(1)
    assert [(it["active"], it["efficiency"]) for it in c.per_iteration] == \
        [(int((x > k).sum()), int((x > k).sum()) / (32 * int((warp_longest > k).sum()))) for k in range(x.max())]


def test_per_iteration_figures_are_dicts_when_read_and_no_objects_before():
    """PhaseCounter.per_iteration keeps its figures as columns (StepFigures): read, each is the dict
    the plots and RenderResult.iterations hand out, in the order added, also after more are added
    behind a read; added, a loop's thousands of figures make no object for Python's garbage
    collector (the cost a counted render saves, toolkit/core/simd.py)."""
    c = PhaseCounter(warp_width=4)
    c.add_stream_step("walk", 5, iteration=0, capacity=16, draining=True)
    assert c.per_iteration == [{"phase": "walk", "iteration": 0, "efficiency": 5 / 8, "active": 5,
                                "capacity": 16, "draining": True}]
    c.add_loop_iterations("connect", [2, 1, 0, 0, 0, 0, 0, 0], first_iteration=1)
    c.add_step("generate", 0, 0, iteration=3)
    assert list(c.per_iteration) == [
        {"phase": "walk", "iteration": 0, "efficiency": 5 / 8, "active": 5, "capacity": 16, "draining": True},
        {"phase": "connect", "iteration": 1, "efficiency": 2 / 4, "active": 2, "capacity": 8, "draining": False},
        {"phase": "connect", "iteration": 2, "efficiency": 1 / 4, "active": 1, "capacity": 8, "draining": False},
        {"phase": "generate", "iteration": 3, "efficiency": 1.0, "active": 0, "capacity": 0, "draining": False}]
    assert len(c.per_iteration) == 4 and c.per_iteration[-1]["phase"] == "generate"
    lengths = np.random.default_rng(5).integers(0, 3000, 4096)
    counter = PhaseCounter(warp_width=32)
    gc.collect()
    gc.disable()
    try:
        before = len(gc.get_objects())
        for first in range(0, 30_000, 3000):
            counter.add_loop_iterations("connect", lengths, first_iteration=first)
        made = len(gc.get_objects()) - before
    finally:
        gc.enable()
    assert len(counter.per_iteration) >= 29_000 and made < 100, made     # len() makes no dict


@pytest.fixture(scope="module")
def talk_figures(cornell_box):
    """The SIMD counters on cornell_box at W = 32, with a budget (128x128, 32 spp = 524k
    samples) many times the stream size (32k), so the drain at the end of a pass is a small part."""
    return {t: toolkit.render(cornell_box, technique=t, spp=32, seed=0, resolution=(128, 128)).stats["simd_efficiency"]
            for t in ["pt_naive", "pt_inplace_regen", "pt_compact_regen"]}


def test_naive_efficiency_is_low_like_the_talk(talk_figures):
    # Talk: ~33%. Ours uses Mitsuba's roulette (from depth 5, q = min(max throughput, 0.95)).
    print(talk_figures)
    assert 0.20 <= talk_figures["pt_naive"]["overall"] <= 0.50


def test_inplace_regeneration_step_is_poorly_occupied(talk_figures):
    # Talk: ~30% active threads during regeneration.
    eff = talk_figures["pt_inplace_regen"]
    assert eff["generate"] <= 0.45
    assert eff["extend"] > talk_figures["pt_naive"]["extend"]


def test_compacted_stream_keeps_every_phase_busy(talk_figures):
    # Talk: ~99% in every phase.
    eff = talk_figures["pt_compact_regen"]
    for phase in ("generate", "extend", "shadow", "compact", "overall"):
        assert eff[phase] >= 0.97, (phase, eff)


def test_wider_warps_waste_more_lanes(cornell_box):
    eff = [toolkit.render(cornell_box, technique="pt_naive", spp=4, seed=0, resolution=(64, 64),
                          warp_width=w).stats["simd_efficiency"]["overall"] for w in (8, 16, 32, 64)]
    assert eff == sorted(eff, reverse=True) and eff[0] > eff[-1]


@pytest.mark.parametrize("technique", ["pt_inplace_regen", "pt_compact_regen"])
def test_final_drain_is_marked_from_the_step_after_the_last_sample_starts(cornell_box, technique):
    """64x64 at 16 spp is twice the stream: the stream stays full while samples are left to
    start, then drains. The steps marked `draining` (shaded on compare's plot) are one run to
    the end of the pass, and every step before them ran on a full stream."""
    from toolkit.measure.compare import drain_spans
    result = toolkit.render(cornell_box, technique=technique, spp=16, seed=0, resolution=(64, 64))
    steps = [it for it in result.iterations if it["phase"] == "extend"]
    spans = drain_spans(steps)
    assert len(spans) == 1 and spans[0][1] == steps[-1]["iteration"], spans
    before = [it for it in steps if it["iteration"] < spans[0][0]]
    assert len(before) >= 5 and all(it["active"] == it["capacity"] for it in before)
    assert steps[-1]["active"] < steps[-1]["capacity"]


def test_generate_step_per_iteration_adds_up_and_follows_the_path_length(cornell_box):
    """The regeneration step, iteration by iteration (tutorial 2). In place: once the start's
    waves have died out, a slot restarts once per path, so the share of lanes that regenerate in
    a step is 1 / (mean extension steps per path), scattered over every warp; a warp of 32 almost
    always holds one, so that share is also the step's efficiency (the talk's ~30%). 64x64 at
    64 spp is 8 streams: steps 15 .. the drain are the steady state."""
    W = 32
    inplace, compact = (toolkit.render(cornell_box, technique=t, spp=64, seed=3, resolution=(64, 64), warp_width=W)
                        for t in ("pt_inplace_regen", "pt_compact_regen"))
    for result in (inplace, compact):
        steps = [it for it in result.iterations if it["phase"] == "generate" and it["active"] > 0]
        issued = sum(round(it["active"] / it["efficiency"]) for it in steps)
        assert np.isclose(sum(it["active"] for it in steps) / issued, result.stats["simd_efficiency"]["generate"])
        assert sum(it["active"] for it in steps) == 64 * 64 * 64   # every sample started once
    budget = 64 * 64 * 64
    p = budget / sum(it["active"] for it in inplace.iterations if it["phase"] == "extend")
    steady = [it for it in inplace.iterations if it["phase"] == "generate" and it["iteration"] >= 15
              and not it["draining"]]
    assert len(steady) >= 5
    # 0.03: the ended share of 32,768 slots has a binomial standard error of 0.0025, and what is
    # left of the start's waves after step 15 is under 0.02 (seeds 3, 7, 8)
    for it in steady:
        assert abs(it["efficiency"] - p / (1 - (1 - p) ** W)) < 0.03, (it, p)
    # The compacted stream regenerates side by side: only the last warp of a step can be partial.
    for it in (it for it in compact.iterations if it["phase"] == "generate"):
        assert it["efficiency"] == it["active"] / (-(-it["active"] // W) * W)


def test_compare_json_and_bench_from_the_command_line(tmp_path):
    run = subprocess.run([sys.executable, "-m", "toolkit", "compare", "--json", "--no-progress", "--spp", "2",
                          "--resolution", "32x32", "--out", str(tmp_path)], capture_output=True, text=True, check=True)
    table = json.loads(run.stdout.strip().splitlines()[-1])
    assert set(table) == {"pt_naive", "pt_inplace_regen", "pt_compact_regen"}
    for name, row in table.items():
        assert {"seconds", "samples_per_second", "simd_efficiency", "rmse", "out"} <= set(row)
        assert 0 < row["simd_efficiency"]["overall"] <= 1 and "extend" in row["simd_efficiency"]
        assert row["rmse"] is not None and row["rmse"] > 0
    assert (tmp_path / "cornell_box_efficiency_per_iteration.png").is_file()
    assert (tmp_path / "cornell_box_image_strip.png").is_file()
    run = subprocess.run([sys.executable, "-m", "toolkit", "bench", "--json", "--spp", "1", "--resolution", "32x32",
                          "--repeats", "1"], capture_output=True, text=True, check=True)
    report = json.loads(run.stdout.strip().splitlines()[-1])
    assert report["techniques"]["pt_naive"]["ratio_to_pt_naive"] == 1.0
    assert "samples/s" in run.stdout
    # "gpu": whether the measured device is one (issue 24: Oclgrind, which reports every device
    # type, made a CPU-only machine say true and lose the CPU caveat).
    assert report["gpu"] is is_gpu(get_queue().device)     # the subprocess picks the same device
    assert ("Measured on a CPU" in run.stdout) is not report["gpu"]
