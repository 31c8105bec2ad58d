import json
import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "scenes"


sys.path.insert(0, str(ROOT))   # the checkout's toolkit, also when another copy is installed

# Every kernel the suite builds is built with -Werror: a compiler warning fails the test that
# built it, on whichever OpenCL implementation the suite runs (subprocesses inherit this too).
os.environ["TOOLKIT_WERROR"] = "1"


def pytest_report_header(config):
    """The device the suite runs on, so that a failure report says where it ran."""
    try:
        from toolkit.opencl.device import candidates, describe, describe_implementation, get_queue
        device = get_queue().device
        lines = [f"toolkit device: {describe(device)}; {describe_implementation(device)}"]
        others = [f"{c.implementation} ({'usable' if c.usable else c.reason})"
                  for c in candidates() if c.device.int_ptr != device.int_ptr]
        if others:
            lines.append("other OpenCL implementations: " + "; ".join(others))
        return lines
    except Exception as error:  # the header must never stop the run; the tests will say more
        return [f"toolkit device: none ({str(error).splitlines()[0]})"]


def spp_for(technique, spp):
    """Samples per pixel for a test: a bidirectional sample evaluates ~30 connections, each
    with a shadow ray, so on the CPU it costs ~10x a path-tracing sample; its variance is also
    lower. BDPT tests use an eighth of the path tracers' budget (their statistical tolerances
    come from their own measured error, so this only widens the error bars, honestly)."""
    from toolkit.techniques import get_technique
    return max(1, spp // 8) if get_technique(technique)[0].family == "bdpt" else spp


def film_error_techniques():
    """The techniques whose film carries its own standard error (independent samples or passes),
    for the generic technique x scene tests. mlt is left out of those: its samples are correlated
    along each chain, its film has no error of its own, a chain's accept/reject decisions flip
    with float rounding (so two OpenCL implementations give different, equally right images),
    and few mutations per chain carry startup bias. tests/test_mlt.py checks it over
    independent runs (seeds) instead."""
    from toolkit.techniques import TECHNIQUES
    return sorted(name for name, cls in TECHNIQUES.items() if cls.family != "mlt")


def scene_dirs():
    return sorted(p for p in SCENES.iterdir() if (p / "scene.json").is_file())


@pytest.fixture(scope="session")
def queue():
    from toolkit.opencl.device import get_queue
    return get_queue()


@pytest.fixture(scope="session")
def cornell_box():
    from toolkit import load_scene
    return load_scene(SCENES / "cornell_box")


@pytest.fixture(scope="session")
def cornell_spheres():
    from toolkit import load_scene
    return load_scene(SCENES / "cornell_spheres")


@pytest.fixture(scope="session")
def cornell_bunny():
    from toolkit import load_scene
    return load_scene(SCENES / "cornell_bunny")


@pytest.fixture
def python3_kernel(tmp_path, monkeypatch):
    """A 'python3' kernelspec that runs this interpreter, so the notebook sees the same
    environment (toolkit, pyopencl, ...) as the tests, whatever kernelspecs the user has."""
    spec = tmp_path / "jupyter" / "kernels" / "python3"
    spec.mkdir(parents=True)
    (spec / "kernel.json").write_text(json.dumps({
        "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
        "display_name": "Python 3 (tests)", "language": "python"}))
    # JUPYTER_PATH comes before the user's and the environment's kernel folders.
    monkeypatch.setenv("JUPYTER_PATH", os.pathsep.join(
        [str(tmp_path / "jupyter")] + [p for p in [os.environ.get("JUPYTER_PATH")] if p]))
    return "python3"
