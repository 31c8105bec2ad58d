"""SIMD lanes on a CPU (issue 22, toolkit/opencl/lanes.py): on Intel's CPU runtime every technique
renders the same image with lanes on and off, within toolkit.same_image's tolerance for two
compilers (ACROSS_IMPLEMENTATIONS: the vectorized code calls vector versions of sqrt, sin, exp and
contracts differently); the width each render reports is the one in the compiler's build log;
a choice that the device or the environment cannot follow is an error that says why."""
import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import pyopencl as cl
import pytest

import toolkit
from toolkit.core.validate import InputError
from toolkit.opencl import lanes
from toolkit.opencl.device import candidates
from toolkit.verify.same_image import ACROSS_IMPLEMENTATIONS, FLIPS_ALLOWED, compare_images

from conftest import SCENES, spp_for

ROOT = Path(__file__).resolve().parent.parent
INTEL = next((c for c in candidates() if c.usable and lanes.can_choose(c.device)), None)
needs_intel = pytest.mark.skipif(INTEL is None, reason="Intel's CPU runtime is not usable here "
                                                       "(x86-64 Linux: pip install intel-opencl-rt)")
TECHNIQUES = ("pt_naive", "pt_inplace_regen", "pt_compact_regen", "bdpt_naive_connect", "bdpt_parallel_connect")


@needs_intel
@pytest.mark.parametrize("technique", TECHNIQUES)
def test_lanes_on_and_off_render_the_same_image(technique):
    # max_depth 8: where the vectorizer once gave wrong, run-to-run varying images (issue 17).
    scene = replace(toolkit.load_scene(SCENES / "cornell_box"), max_depth=8)
    renders = {setting: toolkit.render(scene, technique=technique, spp=spp_for(technique, 8), seed=3,
                                       resolution=(16, 16), device=INTEL.selector, lanes=setting, count_simd=False)
               for setting in ("off", "on")}
    check = compare_images(f"{technique}: lanes on = lanes off", renders["on"].image, renders["off"].image,
                           ACROSS_IMPLEMENTATIONS, FLIPS_ALLOWED)
    assert check.passed, check.detail
    off, on = renders["off"].stats, renders["on"].stats
    assert (off["lanes"], on["lanes"]) == ("off", "on")
    # Widths from the compiler's log (a program from pyopencl's cache brings the log it was built with).
    assert off["vector_widths"] and set(off["vector_widths"].values()) == {1}, off["vector_widths"]
    assert set(on["vector_widths"]) == set(off["vector_widths"]) and on["vector_width"] > 1, on["vector_widths"]


def test_the_width_is_read_from_the_compilers_log():
    log = ('Device build done\nremark: <unknown>:0:0: Kernel was 16-way vectorized\n'
           'Kernel "extend_in_place" was successfully vectorized (16)\nKernel "gather" was not vectorized\nDone.')
    widths = lanes.vector_widths(log)
    assert widths == {"extend_in_place": 16, "gather": 1} and lanes.width(widths) == 16
    assert lanes.vector_widths("") == {} and lanes.width({}) is None
    assert "16 work-items per vector in 1 of 2 kernels" in lanes.describe("on", widths)


def _device(platform, kind):
    return SimpleNamespace(platform=SimpleNamespace(name=platform), type=kind)


def test_a_choice_the_device_or_the_environment_cannot_follow_is_an_error(monkeypatch):
    intel = _device("Intel(R) OpenCL", cl.device_type.CPU)
    pocl = _device("Portable Computing Language", cl.device_type.CPU)
    gpu = _device("NVIDIA CUDA", cl.device_type.GPU)
    for variable in ("TOOLKIT_LANES", "CL_CONFIG_USE_VECTORIZER", "CL_CONFIG_CPU_VECTORIZER_MODE"):
        monkeypatch.delenv(variable, raising=False)
    assert [lanes.setting_for(intel), lanes.setting_for(intel, "on"), lanes.setting_for(pocl)] == ["off", "on", None]
    assert lanes.setting_for(gpu) == lanes.HARDWARE
    with pytest.raises(InputError, match="needs Intel's CPU runtime"):
        lanes.setting_for(pocl, "on")
    with pytest.raises(InputError, match="always runs work-items as the lanes of its warps"):
        lanes.setting_for(gpu, "off")
    with pytest.raises(InputError, match="lanes must be 'on' or 'off'"):
        lanes.setting_for(intel, "sideways")
    monkeypatch.setenv("TOOLKIT_LANES", "on")     # the default where the toolkit can choose; ignored elsewhere
    assert (lanes.setting_for(intel), lanes.setting_for(pocl)) == ("on", None)
    monkeypatch.setenv("CL_CONFIG_USE_VECTORIZER", "False")   # the user's: fixes the whole process
    with pytest.raises(InputError, match="CL_CONFIG_USE_VECTORIZER=False is set"):
        lanes.setting_for(intel)
    monkeypatch.delenv("TOOLKIT_LANES")
    assert lanes.setting_for(intel) == "off" and lanes.source_prefix("off") == ""   # no attribute to conflict


@needs_intel
def test_render_says_its_lanes_and_a_bad_setting_is_refused(tmp_path):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    render = [sys.executable, "-m", "toolkit", "render", "--device", INTEL.selector, "--spp", "1", "--resolution",
              "8x8", "--no-progress", "--out", str(tmp_path / "x.png")]
    run = subprocess.run([*render, "--lanes", "on", "--json"], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stderr
    stats = json.loads(run.stdout.splitlines()[-1])
    assert stats["lanes"] == "on" and stats["vector_width"] == max(stats["vector_widths"].values()) > 1
    assert stats["lanes_summary"] in run.stdout
    run = subprocess.run(render, cwd=ROOT, env=dict(env, TOOLKIT_LANES="sideways"), capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 2 and "TOOLKIT_LANES must be 'on' or 'off'" in run.stderr, run.stderr
    assert "Traceback" not in run.stderr


@needs_intel
def test_bench_runs_both_settings_interleaved_and_compare_says_which(tmp_path):
    from toolkit.measure.bench import bench, format_bench
    from toolkit.measure.compare import compare, format_table
    report = bench("scenes/cornell_box", ("pt_naive",), spp=1, resolution=(8, 8), repeats=1, device=INTEL.selector,
                   lanes=("off", "on"))
    off, on = report["techniques"]["pt_naive [lanes off]"], report["techniques"]["pt_naive [lanes on]"]
    assert (off["lanes"], off["vector_width"], on["lanes"]) == ("off", 1, "on") and on["vector_width"] > 1
    assert on["ratio_to_lanes_off"] == on["samples_per_second"] / off["samples_per_second"]
    assert f"on ({on['vector_width']})" in format_bench(report)
    table = compare("scenes/cornell_box", ["pt_naive"], 1, resolution=(8, 8), out_dir=tmp_path, device=INTEL.selector,
                    plots=False, lanes="on")
    assert table["pt_naive"]["lanes"] == "on" and table["pt_naive"]["lanes_summary"] in format_table(table)
