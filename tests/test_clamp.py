"""Firefly clamping, the scene's `integrator.clamp` (scenes/FORMAT.md): a contribution whose largest
RGB component exceeds the clamp is scaled down to it. The path tracers clamp each sample where the
film sums it (cl/film_reduce.cl; tests/test_film.py), BDPT each connection on the device
(cl/bdpt.h), mlt refuses it. What the clamp does to the error (less variance, a bias) is tested
by the study: tests/test_study.py."""
import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import toolkit
from toolkit.core.scene import SceneError, load_scene

SCENES = Path(__file__).resolve().parent.parent / "scenes"


def scene_with(tmp_path, **integrator):
    folder = tmp_path / "box"
    shutil.copytree(SCENES / "cornell_box", folder)
    data = json.loads((folder / "scene.json").read_text())
    data["integrator"].update(integrator)
    (folder / "scene.json").write_text(json.dumps(data))
    return folder


def test_clamp_in_scene_json(tmp_path):
    assert load_scene(scene_with(tmp_path, clamp=None)).clamp is None
    assert "CLAMP" not in load_scene(SCENES / "cornell_box").features()   # other scenes build unchanged
    scene = load_scene(scene_with(tmp_path / "a", clamp=5))
    assert scene.clamp == 5.0 and scene.features()["CLAMP"] == 5.0
    with pytest.raises(SceneError, match=r"integrator.clamp 0.0 is outside 1e-06 \.\. 1e\+10"):
        load_scene(scene_with(tmp_path / "b", clamp=0))
    with pytest.raises(SceneError, match="integrator.clamp"):
        load_scene(scene_with(tmp_path / "c", clamp="high"))


def render_all(scene, techniques):
    return {t: toolkit.render(scene, technique=t, spp=4, resolution=(8, 8), seed=3, count_simd=False).image
            for t in techniques}


def test_every_technique_of_a_family_clamps_the_same_samples():
    """The path tracers compute the same samples and so clamp the same values, whatever order
    their shadow rays land in; both BDPT connect phases clamp the same connections. (At 8x8
    light tracing carries much of the light in small connections: a clamp of 0.2 bites a few.)"""
    scene = dataclasses.replace(load_scene(SCENES / "cornell_spheres"), clamp=0.2)
    pt = render_all(scene, ["pt_naive", "pt_inplace_regen", "pt_compact_regen"])
    assert max(image.max() for image in pt.values()) <= 0.2 + 1e-6     # a mean of samples each <= 0.2
    for image in pt.values():
        np.testing.assert_allclose(image, pt["pt_naive"], rtol=1e-5, atol=1e-6)
    bd = render_all(scene, ["bdpt_naive_connect", "bdpt_parallel_connect"])
    np.testing.assert_allclose(bd["bdpt_naive_connect"], bd["bdpt_parallel_connect"], rtol=1e-5, atol=1e-6)
    free = render_all(dataclasses.replace(scene, clamp=None), ["pt_naive", "bdpt_parallel_connect"])
    assert free["pt_naive"].max() > 1.5
    assert free["bdpt_parallel_connect"].mean() > bd["bdpt_parallel_connect"].mean()   # energy removed


def test_mlt_refuses_a_clamp_and_says_why():
    scene = dataclasses.replace(load_scene(SCENES / "cornell_box"), clamp=1.0)
    with pytest.raises(ValueError, match="mlt does not clamp"):
        toolkit.render(scene, technique="mlt", spp=1, resolution=(8, 8))
