"""The model of a GPU's wall time (toolkit/measure/gpu_model.py, issue 48 item 5): its formula on
cases worked by hand, and its validation against the one GPU run on record (the H200's bench,
results/gpu.md), from the host meter's figures of the code that run measured (commit 2221915,
metered on this CPU by results/issue48/meter_at_commit.py)."""
import json
from pathlib import Path

import pytest

from toolkit.cli import main
from toolkit.measure import gpu_model

ROOT = Path(__file__).resolve().parent.parent
H200 = ROOT / "results" / "gpu" / "2026-12-04_h200" / "gpucheck.json"
RENDERS_2221915 = ROOT / "results" / "issue48" / "host_meter_2221915_h200_bench.json"
METER = ROOT / "results" / "issue48" / "host_meter_before_gpu_sizes.json"
CPU_METER = ROOT / "results" / "issue48" / "host_meter_before_cpu_sizes.json"
# The stated factor: the model, with the host as fast as this loaded 2-core CPU (host_speed 1), gave
# each technique's wall time on the H200 within this factor of what the H200 measured (1.7x to 3.9x
# above it: the H200 machine's host ran the same Python faster). A change of the model that makes it
# worse than this fails here.
FACTOR = 4.0


def load(path):
    return json.loads(path.read_text())


def test_the_formula_on_cases_worked_by_hand():
    figures = {"cpu_seconds": 0.010, "serial_seconds": 0.004, "drains": 100, "read_bytes": 25_000_000, "write_bytes": 0}
    # Kernels longer than the overlapped host (6 ms): serial 4 + kernels 8 + 100 round trips of 20 us + 1 ms of transfer.
    assert gpu_model.predict_render(figures, 0.008) == pytest.approx(0.004 + 0.008 + 100 * 20e-6 + 1e-3)
    # Kernels shorter: the host's 6 overlapped ms count instead.
    assert gpu_model.predict_render(figures, 0.001) == pytest.approx(0.004 + 0.006 + 2e-3 + 1e-3)
    # A host twice as fast halves both host terms.
    assert gpu_model.predict_render(figures, 0.001, host_speed=0.5) == pytest.approx(0.002 + 0.003 + 2e-3 + 1e-3)


def test_kernel_times_come_from_the_gpu_or_a_sibling_scaled():
    gpucheck = load(H200)
    recorded = gpu_model.gpu_kernel_ns(gpucheck)
    # pt_compact_regen: 4.37 ms of kernels for 368 x 368 x 16 samples on the H200 (results/gpu.md: 4.4 ms).
    assert recorded["pt_compact_regen"] == pytest.approx(4.37e6 / (368 * 368 * 16), rel=0.01)
    cpu = {"pt_inplace_regen": 1000.0, "pt_naive": 500.0}
    ns, why = gpu_model.kernel_ns_on_gpu("pt_naive", gpucheck, cpu)
    eff = {t: gpucheck["compare"][t]["simd_efficiency"]["overall"] for t in ("pt_naive", "pt_inplace_regen")}
    assert ns == pytest.approx(500 * recorded["pt_inplace_regen"] / 1000 * eff["pt_inplace_regen"] / eff["pt_naive"])
    assert "pt_inplace_regen" in why
    with pytest.raises(ValueError, match="no kernel time for mlt"):
        gpu_model.kernel_ns_on_gpu("mlt", gpucheck, {})


def test_the_model_reproduces_the_h200s_measured_wall_time_within_the_stated_factor():
    checked = gpu_model.against_measured(load(RENDERS_2221915)["techniques"], load(H200))
    assert set(checked) == {"pt_naive", "pt_inplace_regen", "pt_compact_regen", "bdpt_naive_connect",
                            "bdpt_parallel_connect", "mlt"}
    # bdpt_parallel_connect: 368 x 368 x 2 samples at the 1,572,651 samples/s the H200's bench measured.
    assert checked["bdpt_parallel_connect"]["measured_seconds"] == pytest.approx(368 * 368 * 2 / 1_572_651)
    for name, row in checked.items():
        assert 1 / FACTOR <= row["ratio"] <= FACTOR, (name, row)
    print(gpu_model.format_validation(checked))


def test_the_prediction_for_todays_code_and_its_command(capsys):
    prediction = gpu_model.predict(load(METER), load(H200), load(CPU_METER))
    rows = prediction["techniques"]
    for row in rows.values():
        assert row["wall_ns"] >= max(row["kernel_ns"], row["host_ns"])   # the host's time never shrinks in it
        assert 0 < row["kernel_share"] <= 1 and row["gpu_over_cpu"] > 0
    ratio = prediction["ratios"]["parallel over naive connect"]
    assert ratio["wall"] == pytest.approx(rows["bdpt_naive_connect"]["wall_ns"] / rows["bdpt_parallel_connect"]["wall_ns"])
    assert main(["bench", "--predict-gpu", str(H200), "--meter", str(METER), "--cpu-meter", str(CPU_METER),
                 "--json"]) == 0
    out = capsys.readouterr().out
    assert main(["bench", "--predict-gpu", str(H200), "--meter", str(METER), "--host-speed", "0.5", "--json"]) == 0
    faster = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["techniques"]["bdpt_parallel_connect"]
    assert faster["host_ns"] == pytest.approx(rows["bdpt_parallel_connect"]["host_ns"] / 2)
    assert "a model, not a measurement" in out and json.loads(out.strip().splitlines()[-1]) == json.loads(json.dumps(prediction))


def test_serial_time_counts_only_where_the_extra_samples_drained():
    """The meter's serial figure is counted where the extra samples made drains; where they made none
    it is the noise of the renders' fixed drains, and the model counts none (gpu_model assumption 2)."""
    meter = load(METER)
    row = meter["techniques"]["pt_inplace_regen"]
    assert row["drains_per_million"] > 0 and row["serial_ns_per_sample"] > 0
    drained = gpu_model.predict(meter, load(H200))["techniques"]["pt_inplace_regen"]
    assert drained["serial_ns"] == pytest.approx(row["serial_ns_per_sample"])
    row["drains_per_million"] = 0.0
    quiet = gpu_model.predict(meter, load(H200))["techniques"]["pt_inplace_regen"]
    assert quiet["serial_ns"] == 0.0 and quiet["round_trip_ns"] == 0.0
    assert quiet["wall_ns"] == pytest.approx(max(quiet["kernel_ns"], quiet["host_ns"]) + quiet["link_ns"])


def test_bad_reports_are_refused_with_exit_code_2(tmp_path, capsys):
    (tmp_path / "not.json").write_text("{")
    (tmp_path / "list.json").write_text("[]")
    for argv, message in ((["--predict-gpu", str(tmp_path / "missing.json")], "cannot read"),
                          (["--predict-gpu", str(tmp_path / "not.json")], "is not JSON"),
                          (["--predict-gpu", str(tmp_path / "list.json")], "holds no report"),
                          (["--predict-gpu", str(METER)], "not a gpucheck report"),
                          (["--predict-gpu", str(H200), "--meter", str(H200)], "not a host meter report"),
                          (["--meter", str(METER)], "go with --predict-gpu"),
                          (["--predict-gpu", str(H200), "--meter", str(METER), "--host-speed", "0"], "above 0")):
        assert main(["bench", *argv]) == 2, argv
        assert message in capsys.readouterr().err
