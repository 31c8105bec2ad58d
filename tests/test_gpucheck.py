"""`python -m toolkit gpucheck --fast` on the suite's device (PoCL here; issue 14, check 5): it
runs every step, writes one report (text and JSON) that names the device, its warp width and
stream/pool sizes, samples/s per technique and the talk's ratios, and its exit code follows
the correctness checks."""
import json

import numpy as np
import pytest

import toolkit.api
from toolkit.verify import cpu_references as cpu_references_module

from toolkit.verify import same_image
import toolkit.cli.gpucheck_run as gpucheck
from toolkit.cli import main
from toolkit.opencl.device import get_queue
from toolkit.opencl.device_model import device_warp_width
from toolkit.opencl.work_sizes import device_work_sizes
from toolkit.measure.host_meter import HOST_DEFAULT


@pytest.fixture(scope="module")
def cpu_references(tmp_path_factory):
    """CPU reference images as they are carried to a GPU machine (toolkit/verify/cpu_references.py),
    made here on the suite's device: the same samples, so they must agree."""
    folder = tmp_path_factory.mktemp("cpu_references")
    assert main(["gpucheck", "--write-cpu-references", str(folder)]) == 0
    return folder


@pytest.fixture(scope="module")
def fast_run(tmp_path_factory, cpu_references):
    out = tmp_path_factory.mktemp("gpucheck") / "report.txt"
    code = main(["gpucheck", "--fast", "--out", str(out), "--cpu-references", str(cpu_references)])
    return code, out, json.loads(out.with_suffix(".json").read_text())


def test_fast_gpucheck_passes_and_reports_what_the_issue_asks(fast_run):
    code, out, report = fast_run
    assert code == 0 and report["passed"]
    device = get_queue().device
    sizes = device_work_sizes(device)
    d = report["device"]
    assert (d["warp_width"], d["stream_size"], d["pool_size"]) == (device_warp_width(device)[0], sizes.stream_size,
                                                                   sizes.pool_size)
    steps = {c["step"] for c in report["checks"]}
    assert steps == {"same image", "CPU reference", "Embree", "compare"}
    assert sum(c["step"] == "same image" for c in report["checks"]) >= 11
    assert sum(c["step"] == "CPU reference" for c in report["checks"]) == len(cpu_references_module.RENDERS)
    assert set(report["phases"]) == set(gpucheck.PHASE_TECHNIQUES) and report["complete"]
    assert set(report["bench"]["techniques"]) == set(gpucheck.BENCH_TECHNIQUES)
    assert all(row["samples_per_second"] > 0 for row in report["bench"]["techniques"].values())
    for label, (a, b, talk) in gpucheck.TALK_RATIOS.items():
        rates = report["bench"]["techniques"]
        assert report["ratios"][label]["ratio"] == pytest.approx(rates[a]["samples_per_second"] /
                                                                 rates[b]["samples_per_second"])
    assert report["compare"]["pt_compact_regen"]["simd_efficiency"]["overall"] > 0
    host = report["host_meter"]
    assert set(host["techniques"]) == set(HOST_DEFAULT) and host["resolution"] == [32, 32]
    for row in host["techniques"].values():   # the host meter's figures (tests/test_host_meter.py checks its counts)
        assert row["launches_per_pass"] > 0 and 0 < row["kernel_share"] <= 1 and row["read_bytes_per_sample"] >= 0
    text = out.read_text()
    assert "host meter: cornell_box 32x32" in text
    assert f"stream {sizes.stream_size:,} paths" in text and "talk 1.20x" in text and "talk 1.15x" in text
    if not d["gpu"]:
        assert "GPU against CPU: only a CPU here" in text and not report["gpu_vs_cpu"]["measured"]


def test_a_failed_check_fails_the_run(fast_run, monkeypatch, capsys):
    _, out, report = fast_run
    report = dict(report, checks=[dict(c) for c in report["checks"]])
    report["checks"][0]["passed"] = False
    report["passed"] = False
    monkeypatch.setattr(gpucheck, "run", lambda **kwargs: report)
    assert main(["gpucheck", "--fast", "--out", str(out.with_name("failed.txt"))]) == 1
    assert "FAIL  same image" in capsys.readouterr().out


def test_a_sample_scheduling_bug_fails_the_same_image_check(cornell_box, monkeypatch):
    """One pixel of pt_compact_regen's image off by one sample of radiance 1 (a sample counted
    twice, say): the checks that compare that image fail, and only they."""
    real = toolkit.api.render

    def render(*args, **kwargs):
        result = real(*args, **kwargs)
        if kwargs.get("technique") == "pt_compact_regen" and not kwargs.get("options"):
            result.image[3, 5] += 1 / 8               # 8 samples per pixel
        return result
    monkeypatch.setattr(toolkit.api, "render", render)
    checks = same_image.same_image_checks(cornell_box, resolution=(8, 8), spp=8)
    failed = [c.name for c in checks if not c.passed]
    assert failed == ["pt_compact_regen = pt_naive", "pt_compact_regen: stream_size 128 = the device's"]


def test_a_wrong_cpu_reference_fails_its_check_and_only_it(cpu_references, tmp_path):
    """A row of reference pixels off by a sample's worth (what a GPU that lost a sample in each
    pixel of a work-group would show; a pixel or four may differ by a near tie, FLIPS_ALLOWED):
    that reference's check fails, the others pass."""
    folder = tmp_path / "refs"
    folder.mkdir()
    for path in cpu_references.iterdir():
        (folder / path.name).write_bytes(path.read_bytes())
    name = cpu_references_module.file_name("cornell_box", "pt_compact_regen")
    image = np.load(folder / name)
    image[10, :] += 1 / 8
    np.save(folder / name, image)
    checks = cpu_references_module.checks(folder)
    assert [c.name.split(" = ")[0] for c in checks if not c.passed] == ["pt_compact_regen on cornell_box"]


@pytest.mark.parametrize("change, message", [
    (lambda m: m["entries"][0].update(scene="../../etc"), "is not a bundled scene"),
    (lambda m: m["entries"][0].update(file="../outside.npy"), "must be a plain .npy name"),
    (lambda m: m["entries"][0].update(technique="mlt"), "depend on its chain count"),
    (lambda m: m["entries"][0].update(resolution=[64, 10**6]), "resolution must be"),
    (lambda m: m.update(entries="all"), "'entries' must be a list"),
    (lambda m: m["entries"][0].update(file="link.npy"), "is a link"),
])
def test_a_bad_cpu_reference_folder_is_refused_before_any_work(cpu_references, tmp_path, capsys, change, message):
    folder = tmp_path / "refs"
    folder.mkdir()
    for path in cpu_references.iterdir():
        (folder / path.name).write_bytes(path.read_bytes())
    (folder / "link.npy").symlink_to(next(cpu_references.glob("*.npy")))
    manifest = json.loads((folder / "references.json").read_text())
    change(manifest)
    (folder / "references.json").write_text(json.dumps(manifest))
    assert main(["gpucheck", "--fast", "--out", str(tmp_path / "r.txt"), "--cpu-references", str(folder)]) == 2
    assert message in capsys.readouterr().err and not (tmp_path / "r.txt").exists()


def test_a_bad_report_name_is_refused_before_any_work(tmp_path, capsys):
    assert main(["gpucheck", "--fast", "--out", str(tmp_path / "report.png")]) == 2
    assert "give a .txt name" in capsys.readouterr().err


def test_images_agree_check_names_the_worst_pixel():
    a = np.ones((40, 50, 3))
    check = same_image.compare_images("x", a * (1 + 2e-5), a, same_image.SAME_DEVICE)
    assert not check.passed and "1.8 of the tolerance" in check.detail
    assert not same_image.compare_images("x", a * np.nan, a, same_image.SAME_DEVICE).passed
    # Across implementations, up to 0.1% of the pixels (here 2 of 2000) may exceed it: near-tie flips.
    b = a.copy()
    b[0, :2, 0] += 1e-3
    assert same_image.compare_images("x", b, a, same_image.ACROSS_IMPLEMENTATIONS, same_image.FLIPS_ALLOWED).passed
    b[0, 2, 0] += 1e-3
    check = same_image.compare_images("x", b, a, same_image.ACROSS_IMPLEMENTATIONS, same_image.FLIPS_ALLOWED)
    assert not check.passed and "3 of 2000 pixels beyond it (allowed: 2)" in check.detail
    assert not same_image.compare_images("x", b, a, same_image.SAME_DEVICE).passed
