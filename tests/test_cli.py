"""The command line (`python -m toolkit ...`, run as a learner would, in a subprocess) and
`toolkit.render()` from Python."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
SUMMARY_KEYS = {"scene", "technique", "spp", "resolution", "seconds", "samples_per_second",
                "device", "out", "mean", "nonfinite"}


def run_cli(*args, cwd=ROOT, timeout=300):
    # PYTHONPATH: the toolkit need not be installed, and cwd may be outside the checkout.
    path = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    return subprocess.run([sys.executable, "-m", "toolkit", *args], cwd=cwd,
                          env=dict(os.environ, PYTHONPATH=path),
                          capture_output=True, text=True, timeout=timeout)


def summary(result):
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    lines = result.stdout.strip().splitlines()
    stats = json.loads(lines[-1])
    assert isinstance(stats, dict)
    missing = SUMMARY_KEYS - set(stats)
    assert not missing, missing
    return stats


def test_render_json_summary_matches_the_written_images(tmp_path):
    out = tmp_path / "x.exr"
    stats = summary(run_cli("render", "--json", "--spp", "2", "--resolution", "16x16",
                            "--out", str(out), "--no-progress"))
    assert stats["scene"] == "cornell_box"
    assert stats["technique"] == "pt_naive"
    assert stats["spp"] == 2
    assert stats["resolution"] == [16, 16]
    assert stats["nonfinite"] == 0
    assert stats["seconds"] > 0 and stats["samples_per_second"] > 0
    assert Path(stats["out"]) == out
    assert isinstance(stats["device"], str) and stats["device"]
    assert len(stats["mean"]) == 3 and all(np.isfinite(stats["mean"])) and min(stats["mean"]) > 0
    assert out.is_file() and out.with_suffix(".png").is_file()

    import OpenImageIO as oiio
    from toolkit.core.images import read_exr
    image = read_exr(out)
    assert image.shape == (16, 16, 3)
    assert np.isfinite(image).all()
    np.testing.assert_allclose(image.reshape(-1, 3).mean(0), stats["mean"], rtol=1e-5)
    for path in (out, out.with_suffix(".png")):
        file = oiio.ImageInput.open(str(path))
        assert file is not None, oiio.geterror()
        try:
            spec = file.spec()
            assert (spec.width, spec.height, spec.nchannels) == (16, 16, 3), path
        finally:
            file.close()


def test_render_json_with_no_other_argument_uses_the_readme_defaults(tmp_path):
    """The usage page's (docs/usage.md) `python -m toolkit render --json`: bundled Cornell box, 256x256, 64 spp,
    written under out/ of the working directory."""
    stats = summary(run_cli("render", "--json", cwd=tmp_path))
    assert stats["scene"] == "cornell_box"
    assert stats["technique"] == "pt_naive"
    assert stats["spp"] == 64
    assert stats["resolution"] == [256, 256]
    assert stats["nonfinite"] == 0
    out = tmp_path / "out" / "cornell_box_pt_naive.exr"
    assert (tmp_path / stats["out"]).resolve() == out.resolve()
    assert out.is_file() and out.with_suffix(".png").is_file()
    # The bundled scene has a reference: the summary compares with it.
    assert "rmse" in stats and stats["rmse"] < 0.1


def test_devices_lists_devices_and_the_pick():
    result = run_cli("devices")
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    assert "OpenCL devices" in result.stdout
    assert "0:0" in result.stdout
    assert "The toolkit would pick:" in result.stdout
    # which way each device sums BDPT's records (toolkit/opencl/record_film.py: film_path)
    assert "BDPT's film (connection records summed per pixel on the device): exact 128-bit" in result.stdout
    # and where the path tracers' film adds its passes (toolkit/opencl/device_film.py: film_path)
    assert "path tracers' film (each pass's sums per pixel): float64 sums " in result.stdout


@pytest.mark.parametrize("args,complaint", [
    (["--resolution", "0x5"], "argument --resolution: expected WIDTHxHEIGHT"),
    (["--resolution", "64"], "argument --resolution: expected WIDTHxHEIGHT"),
    (["--technique", "nope"], "argument --technique: invalid choice: 'nope'"),
    (["--spp", "0"], "argument --spp: must be at least 1"),
    (["--spp", "many"], "argument --spp: expected a whole number"),
], ids=["zero-width", "no-height", "unknown-technique", "zero-spp", "spp-not-a-number"])
def test_bad_arguments_get_usage_and_the_reason(args, complaint, tmp_path):
    result = run_cli("render", *args, cwd=tmp_path)
    assert result.returncode != 0
    assert "Traceback" not in result.stderr
    assert "usage:" in result.stderr
    assert complaint in result.stderr.splitlines()[-1], result.stderr
    assert not (tmp_path / "out").exists()


def test_no_command_prints_usage_without_traceback():
    result = run_cli()
    assert result.returncode != 0
    assert "usage:" in result.stderr and "Traceback" not in result.stderr


def test_every_command_is_registered_with_its_help_and_handler():
    """toolkit/cli/: each command module adds its subparser and the function that runs it; the
    shared options (options.py parents) keep one meaning and their place in --help."""
    from toolkit.cli import build_parser
    parser = build_parser()
    commands = next(a for a in parser._actions if a.dest == "command").choices
    assert list(commands) == ["render", "devices", "crosscheck", "compare", "bench", "gpucheck", "study", "grade", "course",
                             "demo"]
    for name, p in commands.items():
        assert callable(p.get_default("run")), name
        options = {o for a in p._actions for o in a.option_strings}
        assert ("--device" in options) == (name != "devices"), name
        text = p.format_help()
        if "--bvh" in options:   # the kernel options come last, under their heading
            kernel = text.split("\nkernel options:\n")[1]
            listed = [line.split()[0] for line in kernel.splitlines() if line.startswith("  --")]
            assert listed == [o for o in ("--bvh", "--general", "--lanes") if o in options], name
    args = parser.parse_args(["--device", "0:0", "render", "--bvh", "binary"])
    assert (args.device, args.bvh, args.general, args.run.__name__) == ("0:0", "binary", False, "cmd_render")
    assert parser.parse_args(["compare", "--device", "1:0"]).device == "1:0"
    assert parser.parse_args(["grade", "mis", "--stub"]).device is None


def test_render_from_python_returns_image_stderr_and_stats():
    import toolkit
    result = toolkit.render(None, technique="pt_naive", spp=2, seed=1, resolution=(24, 16))
    assert result.image.shape == (16, 24, 3)
    assert result.stderr.shape == (16, 24, 3)
    assert np.isfinite(result.image).all() and np.isfinite(result.stderr).all()
    assert (result.stderr >= 0).all()
    assert result.image.mean() > 0
    stats = result.stats
    assert SUMMARY_KEYS - {"out"} <= set(stats)
    assert stats["resolution"] == [24, 16] and stats["spp"] == 2 and stats["nonfinite"] == 0
    np.testing.assert_allclose(stats["mean"], result.image.reshape(-1, 3).mean(0))


def test_render_from_python_rejects_bad_spp():
    import toolkit
    with pytest.raises(ValueError, match="spp"):
        toolkit.render(None, spp=0, resolution=(8, 8))


def test_device_option_before_or_after_the_command(tmp_path):
    out = str(tmp_path / "d.exr")
    for args in (["--device", "0:0", "render"], ["render", "--device", "0:0"]):
        result = run_cli(*args, "--json", "--spp", "1", "--resolution", "8x8", "--out", out)
        assert result.returncode == 0, result.stderr
        assert summary(result)["device"]
    bad = run_cli("render", "--device", "9:9", "--spp", "1", "--resolution", "8x8", "--out", out)
    assert bad.returncode == 2 and "no OpenCL device 9:9" in bad.stderr and "Traceback" not in bad.stderr


def test_crosscheck_runs_on_the_device_it_is_given():
    # The best device by its P:D (platform 0 may be the Oclgrind simulator, which the toolkit
    # only uses when named: its wide-BVH hits disagree with Embree, and crosscheck says so).
    from toolkit.opencl.device import candidates
    best = next(c for c in candidates() if c.usable and c.rank[0] < 4)
    ok = run_cli("crosscheck", "--device", best.selector, "--rays", "1000", "--json")
    assert ok.returncode == 0, ok.stderr
    bad = run_cli("crosscheck", "--device", "9:9", "--rays", "1000")
    assert bad.returncode == 2 and "no OpenCL device 9:9" in bad.stderr and "Traceback" not in bad.stderr


def test_equal_time_report_says_what_a_bdpt_sample_costs_and_is_worth():
    """The equal-time summary: cost = seconds per sample relative to the best path tracer,
    worth = squared error x samples relative to it (both of a made-up report)."""
    from toolkit.measure.study import format_equal_time
    report = {"pt_naive": {"spp": 1000, "seconds": 10.0, "rmse": 0.010, "rmse_hard_pixels": 0.01},
              "pt_compact_regen": {"spp": 800, "seconds": 10.0, "rmse": 0.012, "rmse_hard_pixels": 0.01},
              "bdpt_parallel_connect": {"spp": 200, "seconds": 10.0, "rmse": 0.008, "rmse_hard_pixels": 0.004}}
    text = format_equal_time(report, 10)
    assert "best BDPT / best PT RMSE, whole image: 0.80" in text
    # cost (10/200) / (10/1000) = 5.0; worth (0.01^2 * 1000) / (0.008^2 * 200) = 7.8
    assert "one bdpt_parallel_connect sample costs 5.0 pt_naive samples here and is worth 7.8 of them" in text


def test_compare_renders_mlt_alone(tmp_path):
    """mlt alone used to stop at the phase plot (a figure of no rows: `Number of rows must be a positive
    integer, not 0`, exit 2); the plot has panels for the path tracers and BDPT only, so it is left out."""
    result = run_cli("compare", "--techniques", "mlt", "--resolution", "8x8", "--spp", "2", "--no-progress",
                     "--json", "--out", str(tmp_path))
    assert result.returncode == 0, result.stderr
    table = json.loads(result.stdout.strip().splitlines()[-1])
    assert list(table) == ["mlt"] and table["mlt"]["nonfinite"] == 0
    assert "phases" not in table["mlt"]["plots"] and Path(table["mlt"]["out"]).is_file()
