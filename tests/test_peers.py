"""The peer benchmarks (toolkit/peers/mitsuba.py): the Mitsuba converter renders what the toolkit renders,
the Embree figures are measured on the same rays, and without Mitsuba `--peer` says how to install it."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import toolkit
from toolkit.peers import mitsuba as peers
from toolkit.measure.reference import relative_mean_error, z_test

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("name", ["cornell_box", "cornell_spheres"])
def test_the_mitsuba_conversion_renders_the_toolkits_image(request, name):
    """A low-spp Mitsuba image (16 independent passes, for its standard error) agrees with the
    toolkit's pt_naive image within statistical error: per-pixel z-test, Bonferroni-corrected."""
    pytest.importorskip("mitsuba")
    scene = request.getfixturevalue(name)
    res = 16
    mitsuba = peers.MitsubaRenderer(scene, res, res)
    image, stderr, _ = mitsuba.passes(64, 16, seed=1)
    ours = toolkit.render(scene, "pt_naive", spp=1024, seed=5, resolution=(res, res))
    rel = relative_mean_error(image, ours.image)
    # The image means (per channel) agree within 4 standard errors of their difference.
    n = res * res
    se = np.sqrt((stderr ** 2).sum((0, 1)) + (ours.stderr ** 2).sum((0, 1))) / n
    diff = np.abs(image.mean((0, 1)) - ours.image.mean((0, 1)))
    assert np.all(diff < 4 * se), f"{mitsuba.variant}: image means differ by {diff} (standard error {se})"
    test = z_test(image, stderr, ours.image, ours.stderr, alpha=0.01, dof=15)
    print(f"{name}, Mitsuba {mitsuba.variant}: {test}; mean rel error {np.round(rel, 4)}")
    assert test.passed, str(test)


def test_the_converter_follows_the_scene(cornell_spheres, tmp_path):
    d = peers.to_mitsuba(cornell_spheres, tmp_path, 32, 16, spp=4)
    assert d["integrator"] == {"type": "path", "max_depth": cornell_spheres.max_depth,
                               "rr_depth": cornell_spheres.rr_depth, "hide_emitters": False}
    assert d["sensor"]["film"]["rfilter"] == {"type": "box"}
    assert (d["sensor"]["film"]["width"], d["sensor"]["film"]["height"]) == (32, 16)
    shapes = [v for k, v in d.items() if k.startswith("shape_")]
    assert sum(1 for s in shapes if "emitter" in s) >= 1
    kinds = {s["bsdf"]["type"] for s in shapes}
    assert "dielectric" in kinds and "twosided" in kinds     # glass one-sided, the rest two-sided


def test_peer_mitsuba_without_mitsuba_says_how_to_install(tmp_path):
    code = ("import sys; sys.modules['mitsuba'] = None\n"      # makes `import mitsuba` fail
            "from toolkit.cli import main; sys.exit(main(['bench', '--peer', 'mitsuba']))")
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert run.returncode == 2, run.stderr
    assert 'pip install ".[peers]"' in run.stderr
    assert "Traceback" not in run.stderr


def test_embree_figures_are_measured_on_the_same_rays(cornell_box, queue):
    report = peers.embree_rays(cornell_box, n_random=4096, repeats=1, queue=queue)
    assert report["rays"] == {"random": 4096, "camera": cornell_box.camera.width * cornell_box.camera.height,
                              "surface": 4096}
    for row in report["rays_per_second"].values():
        assert set(row) == {"toolkit binary", "toolkit wide", "embreex"} and min(row.values()) > 0
    assert "wide / embree" in peers.format_embree(report)


def test_surface_rays_start_off_their_surface_and_hit_what_embree_hits(cornell_spheres, queue):
    """The rays `bench --peer embree` starts on surfaces: each origin lies the kernels' ray offset
    off its triangle, on its direction's side, so it never hits its own triangle again; and our
    traversal finds the triangle that Embree finds (disagreements only where the cross-check
    excuses them: edges, ties)."""
    from toolkit.opencl.device_scene import DeviceScene
    from toolkit.opencl.raycast import DeviceRaycaster
    from toolkit.peers.embree import EmbreeIntersector, surface_points, surface_rays
    from toolkit.verify.crosscheck import _closest_figures
    ds = DeviceScene(queue, cornell_spheres, bvh="wide")
    origins, dirs = surface_rays(ds, 20_000, np.random.default_rng(3))
    own, points, normals = surface_points(ds, 20_000, np.random.default_rng(3))   # the same draws
    height = ((origins - points) * normals).sum(1)             # signed distance off the triangle's plane
    side = np.sign((dirs * normals).sum(1))
    # At least the scene's epsilon, at most epsilon plus the ulp term and float32 rounding of the
    # origin (a few ulps of its coordinates, far below epsilon = 1e-5 of the scene's size).
    assert (height * side >= 0.5 * ds.epsilon).all() and (np.abs(height) <= 2.0 * ds.epsilon).all()
    embree = EmbreeIntersector(cornell_spheres, center=ds.center)
    dev, emb = DeviceRaycaster(queue, ds).closest(origins, dirs), embree.closest(origins, dirs)
    assert not (dev[1] == own).any() and not (emb[1] == own).any()   # a plane is not hit twice
    figures, _, unexplained = _closest_figures(origins, dirs, dev, emb, embree.triangles)
    assert figures["hits_device"] > 0.5 * len(origins)        # inside the box most rays hit something
    assert not unexplained.any(), figures
