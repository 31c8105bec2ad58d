import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "scenes"


sys.path.insert(0, str(ROOT))   # the checkout's toolkit, also when another copy is installed


def spp_for(technique, spp):
    """Samples per pixel for a test: a bidirectional sample evaluates ~30 connections, each
    with a shadow ray, so on the CPU it costs ~10x a path-tracing sample; its variance is also
    lower. BDPT tests use an eighth of the path tracers' budget (their statistical tolerances
    come from their own measured error, so this only widens the error bars, honestly)."""
    from toolkit.techniques import get_technique
    return max(1, spp // 8) if get_technique(technique)[0].family == "bdpt" else spp


def scene_dirs():
    return sorted(p for p in SCENES.iterdir() if (p / "scene.json").is_file())


@pytest.fixture(scope="session")
def queue():
    from toolkit.device import get_queue
    return get_queue()


@pytest.fixture(scope="session")
def cornell_box():
    from toolkit import load_scene
    return load_scene(SCENES / "cornell_box")


@pytest.fixture(scope="session")
def cornell_spheres():
    from toolkit import load_scene
    return load_scene(SCENES / "cornell_spheres")
