"""compare's time per phase (toolkit/measure/phases.py): every kernel a technique launches is a
phase, the phases' device times fit in the render's wall time, and the plot and the JSON carry
them. Correctness only: no timing ratio is asserted (they are benchmarks, not tests)."""
import json
from collections import Counter

import pyopencl as cl
import pytest

from toolkit.measure.phase_plot import one_run, save_phase_plot
from toolkit.measure.phases import HOST, KERNEL_PHASES, model_rows

TECHNIQUES = ["pt_naive", "pt_inplace_regen", "pt_compact_regen", "bdpt_naive_connect", "bdpt_parallel_connect"]
# Two clocks meet in the bound "kernels <= wall": the device's profiling clock (ns) and the host's
# perf_counter. Both tick in ns or finer and run at the same rate to parts per million, so over a
# render of < 1 s they differ by < 1 us; 1 ms more covers implementations that timestamp a command
# when its completion is noticed rather than when it ends.
CLOCKS = 1e-3


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """compare of each technique at 16x16, 2 spp (the streams and the pool regenerate there), with
    every kernel launch counted by a spy below the toolkit's launch hook: (table, {technique: Counter})."""
    from toolkit.measure.compare import compare
    out = tmp_path_factory.mktemp("phases")
    launches, current = {}, []
    real = cl.enqueue_nd_range_kernel

    def spy(queue, kernel, *args, **kwargs):
        launches.setdefault(current[-1], Counter())[kernel.function_name] += 1
        return real(queue, kernel, *args, **kwargs)

    table = {}
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(cl, "enqueue_nd_range_kernel", spy)
        for name in TECHNIQUES:   # one at a time, so that the spy knows whose launches it sees
            current.append(name)
            table.update(compare("scenes/cornell_box", [name], 2, resolution=(16, 16), out_dir=out, plots=False))
    return table, launches


def test_every_kernel_launched_is_a_phase_with_its_launches(run):
    table, launches = run
    for name in TECHNIQUES:
        rows = {r["kernel"]: r for r in table[name]["phases"] if r["kernel"] != HOST}
        assert {k: r["launches"] for k, r in rows.items()} == dict(launches[name]), name
        assert set(rows) <= set(KERNEL_PHASES), f"{name}: a kernel without a stage: {set(rows) - set(KERNEL_PHASES)}"
    # what the talk's phases are, per technique: each one a kernel of its own here
    stages = {name: {r["stage"] for r in table[name]["phases"]} for name in TECHNIQUES}
    assert {"shadow rays + regenerate + extend: trace", "extend: shade + compact"} <= stages["pt_compact_regen"]
    assert {"regenerate + extend: trace", "extend: shade"} <= stages["pt_inplace_regen"]
    assert {"regenerate", "walk + compact", "connect", "scan"} <= stages["bdpt_parallel_connect"]


def test_phase_times_are_positive_and_fit_in_the_render(run):
    """Launches on an in-order queue never overlap, so their device times add up to at most the
    span from the first start to the last end, which lies inside the render's wall time. The rest
    is the host's (SIMD counter reads after every step, Python, copies): at 16x16 it is most of the
    wall time, so no lower fraction is asserted, only that the rows account for the whole."""
    table, _ = run
    for name, row in table.items():
        kernels = [r for r in row["phases"] if r["kernel"] != HOST]
        assert kernels and all(r["ms"] > 0 and r["launches"] > 0 for r in kernels), name
        total = sum(r["ms"] for r in kernels) / 1e3
        assert total <= row["kernel_span_seconds"] * (1 + 1e-9) + 1e-9 * len(kernels), name
        assert row["kernel_span_seconds"] <= row["seconds"] + CLOCKS, name
        host = next(r for r in row["phases"] if r["kernel"] == HOST)
        assert host["ms"] >= -1e3 * CLOCKS
        assert sum(r["share"] for r in row["phases"]) == pytest.approx(1.0, rel=1e-9)


def test_efficiency_of_a_phase_comes_from_its_counters(run):
    """A kernel's lane efficiency is active / issued over the counters it runs (phases.KERNEL_PHASES)."""
    table, _ = run
    row = table["pt_compact_regen"]
    trace = next(r for r in row["phases"] if r["kernel"] == "pt_compact_regen_trace")   # shadow + generate + extend
    steps = [row["simd_lane_steps"][phase] for phase in ("shadow", "generate", "extend")]
    assert trace["simd_efficiency"] == sum(a for a, _ in steps) / sum(i for _, i in steps)
    naive = next(r for r in table["pt_naive"]["phases"] if r["kernel"] == "pt_naive_render")
    assert naive["simd_efficiency"] == pytest.approx(table["pt_naive"]["simd_efficiency"]["overall"])


def test_model_is_issued_lane_steps_over_the_references(run):
    table, _ = run
    model = model_rows(table)
    assert model["pt_naive"]["predicted"] == model["bdpt_naive_connect"]["predicted"] == 1.0

    def issued(name):
        return sum(i for _, i in table[name]["simd_lane_steps"].values())
    assert model["pt_compact_regen"]["predicted"] == issued("pt_compact_regen") / issued("pt_naive")
    assert model["bdpt_parallel_connect"]["reference"] == "bdpt_naive_connect"


def test_plot_is_a_png_and_refuses_mixed_runs(run, tmp_path):
    table, _ = run
    path = save_phase_plot(tmp_path / "phases.png", table, "test")
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    from matplotlib.image import imread
    assert imread(path).shape[0] > 400       # two families: two rows of panels
    other = dict(table, other={**table["pt_naive"], "lanes": "elsewhere"})
    with pytest.raises(ValueError, match="one device and lanes setting"):
        one_run(other)


def test_compare_json_and_text_carry_the_phase_rows(run):
    """What `compare --json` prints (json.dumps of the table) and its text table hold the phases."""
    from toolkit.cli import build_parser
    from toolkit.measure.compare import format_table
    table, _ = run
    back = json.loads(json.dumps(table))
    assert back["pt_naive"]["phases"] == table["pt_naive"]["phases"]
    from toolkit.opencl.device import get_queue
    from toolkit.opencl.device_film import has_fp64
    film = {"film_reduce", "film_accumulate"} if has_fp64(get_queue().device) else {"film_reduce"}   # device_film.py
    assert {r["kernel"] for r in back["pt_naive"]["phases"]} == {"pt_naive_render", "simd_count_lanes", HOST} | film   # compare counts SIMD
    text = format_table({"bdpt_naive_connect": table["bdpt_naive_connect"]})   # the fixture's rows are separate compares
    assert "The talk's model" in text and all(r["kernel"] in text for r in table["bdpt_naive_connect"]["phases"])
    assert build_parser().parse_args(["compare", "--plot", "x.png"]).plot == "x.png"


def test_a_long_variant_name_keeps_the_tables_columns_apart(run):
    """A variant's name ("bdpt_parallel_connect/direct_scatter", 36 characters) is longer than the
    usual name column: the name is still followed by spaces, and each table's rows line up."""
    from toolkit.measure.compare import format_table
    table, _ = run
    long_name = "bdpt_naive_connect/" + "x" * 30
    text = format_table({long_name: table["bdpt_naive_connect"]})
    rows = [line for line in text.splitlines() if line.startswith(long_name)]
    assert len(rows) >= 3 and all(line[len(long_name):].startswith("  ") for line in rows)
    kernels = [r["kernel"] for r in table["bdpt_naive_connect"]["phases"]]
    starts = {len(line) - len(line[len(long_name):].lstrip()) for line in rows
              if any(line[len(long_name):].lstrip().startswith(k) for k in kernels)}
    assert len(starts) == 1   # the kernel column starts in one place on every row of the phase table
