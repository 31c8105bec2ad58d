import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "scenes"


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
