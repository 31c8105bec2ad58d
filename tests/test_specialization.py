"""Specialized kernels (only what the scene uses) against the general kernel (everything
compiled in, general=True): the same image, and the general one really carries every path."""
import json
from dataclasses import replace

import numpy as np
import pytest

import toolkit
from toolkit.cli import main
from conftest import film_error_techniques, scene_dirs, spp_for
from toolkit.opencl.device_scene import DeviceScene
from toolkit.core.layout import MATERIAL_TYPES
from toolkit.verify.same_image import SAME_DEVICE_BDPT
from toolkit.core.scene import NO_LIMIT, load_scene
from toolkit.techniques import TECHNIQUES


def _same_to_rounding(a, b):
    # Both kernels compute the same samples in the same order: the only difference a compiler
    # may introduce is float32 rounding (a multiply-add fused in one build and not in the other),
    # ~1e-7 relative per operation, so the same-device tolerance of toolkit.verify.same_image holds (on
    # PoCL the images are bit-identical); a lost material or a roulette that fired would change
    # pixels by whole percents.
    np.testing.assert_allclose(a, b, *SAME_DEVICE_BDPT)


@pytest.mark.parametrize("scene_dir", scene_dirs(), ids=lambda p: p.name)
@pytest.mark.parametrize("technique", film_error_techniques())
def test_general_kernel_gives_the_specialized_image(technique, scene_dir):
    """Check 4 of issue 11: for every technique with independent samples (mlt's chains flip an
    accept/reject with the smallest rounding change: see conftest.film_error_techniques; its
    general kernel is built below) on every bundled scene."""
    spp = spp_for(technique, 4)
    images = [toolkit.render(scene_dir, technique=technique, spp=spp, resolution=(8, 8), count_simd=False,
                             general=general) for general in (False, True)]
    assert [r.stats["kernels"] for r in images] == ["specialized", "general"]
    assert images[0].image.max() > 0
    _same_to_rounding(images[0].image, images[1].image)


def test_every_technique_builds_in_general_form(queue):
    """Every technique's .cl compiles with every material and feature on (-Werror, conftest)."""
    scene = load_scene(scene_dirs()[0])
    device_scene = DeviceScene(queue, scene)
    for name, cls in TECHNIQUES.items():
        tech = cls(queue, device_scene, count_simd=False, general=True)
        assert all(tech.defines[f"HAS_{m.upper()}"] for m in MATERIAL_TYPES), name


def test_general_defines_turn_every_path_on():
    """One general kernel serves every bundled scene (they share their depth settings); the
    specialized ones differ by scene and leave out what it does not use."""
    scenes = [load_scene(d) for d in scene_dirs()]
    general = [s.features(general=True) for s in scenes]
    assert all(g == general[0] for g in general)
    assert all(general[0][f"HAS_{m.upper()}"] for m in MATERIAL_TYPES)
    assert general[0]["HAS_SPECULAR"] and general[0]["USE_MAX_DEPTH"] and general[0]["USE_RUSSIAN_ROULETTE"]
    box = next(s for s in scenes if s.name == "cornell_box")
    assert not box.features()["HAS_MIRROR"] and not box.features()["USE_MAX_DEPTH"]
    # No depth limit in the scene: the general kernel's test is compiled in but cannot fire.
    assert box.max_depth < 0 and general[0]["MAX_DEPTH"] == NO_LIMIT


def test_general_kernel_carries_the_materials_a_specialized_one_lacks(queue):
    """The kernel specialized to the Cornell box (diffuse only) has no mirror or glass: on
    cornell_spheres those surfaces absorb every path and the image loses light. The general
    kernel has them: it renders cornell_spheres as the kernel specialized to it does."""
    box = load_scene(scene_dirs()[0].parent / "cornell_box")
    spheres = DeviceScene(queue, load_scene(scene_dirs()[0].parent / "cornell_spheres"))
    cls = TECHNIQUES["pt_naive"]
    own = cls(queue, spheres, count_simd=False).render(16, 16, 4).image()
    general = cls(queue, spheres, count_simd=False, general=True).render(16, 16, 4).image()
    box_kernel = cls(queue, spheres, count_simd=False, extra_defines=box.features()).render(16, 16, 4).image()
    _same_to_rounding(own, general)
    # The spheres cover ~10% of this view; losing them (and what they reflect) changes the image
    # far beyond rounding: at least one pixel loses half its value.
    assert np.max(np.abs(own - box_kernel) / np.maximum(own, 1e-3)) > 0.5


def test_general_kernel_renders_a_glossy_scene(queue):
    """No bundled scene is glossy: a Cornell box with glossy side walls checks that path too."""
    box = load_scene(scene_dirs()[0].parent / "cornell_box")
    materials = [dict(m, type="glossy", alpha=0.2) if i == 1 else m for i, m in enumerate(box.materials)]
    glossy = replace(box, materials=materials)
    assert glossy.features()["HAS_GLOSSY"] and not box.features()["HAS_GLOSSY"]
    for technique in ("pt_naive", "bdpt_parallel_connect"):
        images = [toolkit.render(glossy, technique=technique, spp=spp_for(technique, 4), resolution=(8, 8),
                                 count_simd=False, general=general).image for general in (False, True)]
        _same_to_rounding(*images)


def test_bench_specialization_measures_both_kernels(capsys):
    """`bench --specialization`: both kernels built afresh (not answered by a cache) and measured;
    the general kernel carries more code, so its program binary is larger."""
    assert main(["bench", "--specialization", str(scene_dirs()[0].parent / "cornell_box"), "--techniques",
                 "pt_naive", "--resolution", "8x8", "--spp", "1", "--repeats", "1", "--json"]) == 0
    out = capsys.readouterr().out
    report = json.loads(out.strip().splitlines()[-1])
    entry = report["scenes"]["cornell_box"]["pt_naive"]
    spec, general = entry["specialized"], entry["general"]
    assert general["binary_bytes"] > spec["binary_bytes"] > 0
    assert spec["build_seconds"] > 0 and general["build_seconds"] > 0
    assert entry["speedup"] == pytest.approx(spec["samples_per_second"] / general["samples_per_second"])
    assert "speed-up" in out and "cornell_box:" in out
