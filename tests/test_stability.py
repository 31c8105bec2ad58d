"""Numerical stability at the extremes: scaled and far-away scenes, a closed white furnace,
a tiny very bright light, grazing camera rays, very long paths."""
from dataclasses import replace

import numpy as np
import pytest

import toolkit
from toolkit.measure.reference import reference_at, relative_mean_error, z_test
from toolkit.core.scene import Camera, Scene

from conftest import spp_for, film_error_techniques

RES, SPP = 16, 16384


@pytest.mark.parametrize("technique", film_error_techniques())
@pytest.mark.parametrize("scale, translate", [(1e-3, 0.0), (1e3, 0.0), (1.0, 1e4)],
                         ids=["scaled_1e-3", "scaled_1e3", "translated_1e4"])
def test_transformed_box_matches_reference(cornell_box, technique, scale, translate):
    """Radiance does not change under scaling or translation: the transformed box must still
    match the reference (no self-intersection acne, which darkens, and no leaks, which brighten)."""
    scene = cornell_box.transformed(scale, (translate, translate, translate))
    result = toolkit.render(scene, technique=technique, spp=spp_for(technique, SPP), seed=11, resolution=(RES, RES))
    ref, ref_err = reference_at(cornell_box, RES, RES)
    assert result.stats["nonfinite_samples"] == 0
    assert np.all(relative_mean_error(result.image, ref) < 0.01)
    test = z_test(result.image, result.stderr, ref, ref_err, dof=result.stats["degrees_of_freedom"])
    assert test.passed, f"{scene.name}: {test}"


def furnace_scene(albedo, emission, size=1.0, center=(0.0, 0.0, 0.0)):
    """A closed cube, every face diffuse with `albedo` and emitting `emission` inwards."""
    c = np.asarray(center, np.float64)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float64)
    vertices = corners * size + c
    # Faces wound so that cross(v1 - v0, v2 - v0) points into the cube.
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = np.array([t for a, b, cc, d in quads for t in ((a, b, cc), (a, cc, d))], np.int64)
    v = vertices[tris]
    inward = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    outward = np.einsum("ij,ij->i", inward, c - v.mean(1)) < 0
    tris[outward] = tris[outward][:, ::-1]
    camera = Camera(origin=c + np.array([0.1, 0.2, 0.3]) * size, target=c + np.array([0.5, -0.3, -1.0]) * size,
                    up=np.array([0.0, 1.0, 0.0]), fov_deg=60.0, fov_axis="x", width=16, height=16)
    material = {"name": "grey", "type": "diffuse", "reflectance": np.full(3, albedo), "ior": 1.0, "alpha": 0.0}
    return Scene(name=f"furnace a={albedo}", camera=camera, vertices=vertices, triangles=tris,
                 material_of=np.zeros(len(tris), np.int64), emission_of=np.full((len(tris), 3), emission),
                 materials=[material], max_depth=-1, rr_depth=5)


def test_furnace_normals_point_inwards():
    scene = furnace_scene(0.5, 1.0)
    v = scene.vertices[scene.triangles]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    assert np.all(np.einsum("ij,ij->i", n, -v.mean(1)) > 0)


@pytest.mark.parametrize("technique", film_error_techniques())
@pytest.mark.parametrize("albedo", [0.5, 0.9])
def test_white_furnace_gives_emission_over_one_minus_albedo(technique, albedo):
    """Radiance everywhere in a closed box of albedo a emitting Le is Le / (1 - a) (a geometric
    series over path length; a = 0.9 means paths of ~10 bounces and more, so this also checks long
    paths and the roulette). Tolerance: 0.5% as the issue asks, and the image mean must also lie
    within 5 of its own standard errors. Pixels are independent, but the three channels of a
    grey furnace are the same numbers, so the error of the mean is that of one channel."""
    le = 1.0
    scene = furnace_scene(albedo, le, size=1.0)
    result = toolkit.render(scene, technique=technique, spp=spp_for(technique, 1024), seed=5, resolution=(16, 16))
    expected = le / (1.0 - albedo)
    mean = result.image.mean()
    pixels = result.stderr.shape[0] * result.stderr.shape[1]
    se = (np.sqrt((result.stderr ** 2).sum((0, 1))) / pixels).max()
    print(f"furnace a={albedo}: {mean:.5f} +- {se:.5f}, expected {expected}")
    assert result.stats["nonfinite_samples"] == 0
    assert abs(mean / expected - 1) < 0.005
    assert abs(mean - expected) < 5 * se


def tiny_light_scene(box, shrink):
    """The Cornell box with its light shrunk about its centre by `shrink` (area by shrink^2)
    and its emission raised by 1/shrink^2: the same power from a tiny, very bright light."""
    lights = box.light_triangles
    ids = np.unique(box.triangles[lights])
    vertices = box.vertices.copy()
    centre = vertices[ids].mean(0)
    vertices[ids] = centre + (vertices[ids] - centre) * shrink
    emission = box.emission_of.copy()
    emission[lights] /= shrink ** 2
    return replace(box, vertices=vertices, emission_of=emission, name=f"tiny light x{shrink:g}")


@pytest.mark.parametrize("technique", film_error_techniques())
def test_tiny_bright_light_and_grazing_rays_stay_finite(cornell_box, technique):
    scene = tiny_light_scene(cornell_box, 1e-3)
    result = toolkit.render(scene, technique=technique, spp=256, seed=2, resolution=(32, 32))
    assert np.isfinite(result.image).all() and result.stats["nonfinite_samples"] == 0
    # The room (not the light's own pixels, whose value rests on hitting a 1e-6 target) must
    # agree with pt_naive's render of the same scene, with other samples: per channel within
    # 5 combined standard errors of the room's mean (BDPT gets 16 passes at 256 spp here).
    other = toolkit.render(scene, technique="pt_naive", spp=256, seed=12, resolution=(32, 32))
    ref, _ = reference_at(cornell_box, 32, 32)
    room = ref.max(-1) < 1.0
    def mean_and_error(r):
        return r.image[room].mean(0), np.sqrt((r.stderr[room] ** 2).sum(0)) / room.sum()
    (a, sa), (b, sb) = mean_and_error(result), mean_and_error(other)
    assert np.all(np.abs(a - b) < 5 * np.hypot(sa, sb)), (a, b, sa, sb)

    # Grazing camera rays: the eye just above the floor (above the 5 mm gap under the boxes),
    # looking down at it so the rays meet the floor at 0.3 to 1.2 degrees.
    floor_y = cornell_box.vertices[:, 1].min()
    height = 3e-3 * cornell_box.extent
    camera = replace(cornell_box.camera, origin=np.array([0.0, floor_y + height, 0.95]),
                     target=np.array([0.0, floor_y, 0.0]), fov_deg=20.0)
    grazing = replace(scene, camera=camera, name="grazing")
    result = toolkit.render(grazing, technique=technique, spp=spp_for(technique, 256), seed=3, resolution=(32, 32))
    assert np.isfinite(result.image).all() and result.stats["nonfinite_samples"] == 0
    assert result.image.mean() > 0
