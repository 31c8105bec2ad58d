"""Transforms on shapes and the camera (toolkit/core/transforms.py, scenes/FORMAT.md): each with a
known answer, the order of composition Mitsuba's, face normals under a non-uniform scale, a mirror
that keeps an emitter emitting to its transformed normal's side, and the errors that name the shape.
"""
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from toolkit.core.errors import InputError
from toolkit.core.scene import SceneError, load_scene
from toolkit.core.transforms import (camera_frame, checked, compose, look_at, operations_from_json, place_mesh,
                                     rotate)

ROOT = Path(__file__).resolve().parent.parent
CORNELL = ROOT / "scenes" / "cornell_box"
LIGHT = 7          # shapes[7] of the Cornell box: meshes/light.obj, the one emitter, facing down (-y)


def point(ops, p):
    m = compose(operations_from_json("t", ops))
    return m[:3, :3] @ np.asarray(p, float) + m[:3, 3]


def test_translate():
    assert np.array_equal(point([{"translate": [1, 2, 3]}], [1, 1, 1]), [2, 3, 4])


def test_rotate_is_counter_clockwise_about_its_axis():
    # 90 degrees about +z takes +x to +y (right-hand rule); the axis's length does not matter.
    np.testing.assert_allclose(point([{"rotate": {"axis": [0, 0, 5], "angle_deg": 90}}], [1, 0, 0]), [0, 1, 0],
                               atol=1e-15)
    np.testing.assert_allclose(point([{"rotate": {"axis": [1, 1, 1], "angle_deg": 120}}], [1, 0, 0]), [0, 1, 0],
                               atol=1e-15)


def test_scale_uniform_and_per_axis():
    assert np.array_equal(point([{"scale": 2}], [1, -2, 3]), [2, -4, 6])
    assert np.array_equal(point([{"scale": [1, 2, 3]}], [1, 1, 1]), [1, 2, 3])


def test_matrix_is_row_major():
    rows = [[0, -1, 0, 5], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    assert np.array_equal(point([{"matrix": rows}], [1, 0, 0]), [5, 1, 0])


def test_operations_compose_in_the_order_written():
    # Scale first, then move: 1 -> 2 -> 3. The other order: 1 -> 2 -> 4.
    assert np.array_equal(point([{"scale": 2}, {"translate": [1, 0, 0]}], [1, 0, 0]), [3, 0, 0])
    assert np.array_equal(point([{"translate": [1, 0, 0]}, {"scale": 2}], [1, 0, 0]), [4, 0, 0])


def test_look_at_matches_mitsuba_s_frame():
    m = look_at([1, 2, 3], [1, 2, 10], [0, 1, 0])
    # Local +z to the viewing direction, +y up, +x = up x z (the image's left), origin at origin.
    np.testing.assert_allclose(m[:3, :3], [[1, 0, 0], [0, 1, 0], [0, 0, 1]], atol=1e-15)
    assert np.array_equal(m[:3, 3], [1, 2, 3])
    np.testing.assert_allclose(look_at([0, 0, 0], [1, 0, 0], [0, 1, 0])[:3, 0], [0, 0, -1], atol=1e-15)


def test_the_same_matrices_as_mitsuba_3():
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    T = mi.ScalarTransform4f
    # A unit axis: Mitsuba's rotate takes the axis as given (a longer one is no rotation); ours normalizes.
    axis = (np.array([0.3, -1, 2]) / np.linalg.norm([0.3, -1, 2])).tolist()
    ours = compose([("scale", [1, 2, 3]), ("rotate", axis, 37.0), ("translate", [4, 5, 6]),
                    ("look_at", [1, 2, 3], [0, -1, 5], [0, 1, 0])])
    theirs = (T().look_at(origin=[1, 2, 3], target=[0, -1, 5], up=[0, 1, 0]) @ T().translate([4, 5, 6])
              @ T().rotate(axis, 37.0) @ T().scale([1, 2, 3]))
    np.testing.assert_allclose(ours, np.array(theirs.matrix), rtol=1e-6, atol=1e-6)   # Mitsuba's are float32


# -- meshes: normals, mirrors, singular matrices ------------------------------------------------

def face_normal(v, t):
    n = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


TILTED = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 1]]), np.array([[0, 1, 2]])     # normal (0, -1, 1)/sqrt 2


def test_face_normals_under_a_non_uniform_scale_are_the_inverse_transpose():
    m = checked(compose([("scale", [1, 4, 1])]), "t")
    v, t = place_mesh(m, *TILTED, "t")
    # Known answer: n' ~ A^-T n = (0, -1/4, 1), not A n = (0, -4, 1).
    np.testing.assert_allclose(face_normal(v, t)[0], np.array([0, -0.25, 1]) / math.hypot(0.25, 1), atol=1e-15)


def test_a_mirror_rewinds_so_the_normal_is_the_transformed_one():
    m = checked(compose([("scale", [1, 1, -1])]), "t")
    v, t = place_mesh(m, *TILTED, "t")
    assert np.array_equal(t, [[0, 2, 1]])
    # A^-T n for n = (0, -1, 1)/sqrt 2 and A = diag(1, 1, -1): (0, -1, -1)/sqrt 2. Without the
    # re-winding the winding's normal would be (0, 1, 1)/sqrt 2, the other side.
    np.testing.assert_allclose(face_normal(v, t)[0], np.array([0, -1, -1]) / math.sqrt(2), atol=1e-15)


@pytest.mark.parametrize("ops,problem", [
    ([{"scale": [1, 0, 1]}], "singular"),
    ([{"matrix": [[1, 2, 3, 0], [2, 4, 6, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}], "singular"),
    ([{"scale": 1e-200}, {"scale": 1e-200}], "singular"),      # underflows to a zero matrix
    ([{"matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]}], "last row must be 0 0 0 1"),
    ([{"scale": 1e200}, {"scale": 1e200}], "NaN or infinite entry"),
], ids=["scale-zero", "rank-2-matrix", "underflow", "projective", "overflow"])
def test_a_singular_or_non_finite_matrix_is_refused(ops, problem):
    with pytest.raises(InputError, match=problem):
        checked(compose(operations_from_json("shapes[2].transform", ops)), "shapes[2]")


@pytest.mark.parametrize("ops,problem", [
    ([], "non-empty list"), ({"translate": [1, 2, 3]}, "non-empty list"),
    ([{"translate": [1, 2]}], r"translate: expected 3 numbers"),
    ([{"scale": "2"}], r"scale: expected 3 numbers"),
    ([{"rotate": {"axis": [0, 0, 0], "angle_deg": 3}}], "axis of a rotation cannot be 0 0 0"),
    ([{"rotate": {"axis": [0, 0, 1]}}], "angle_deg"),
    ([{"shear": 1}], "expected one of translate"),
    ([{"translate": [1, 2, 3], "scale": 2}], "as the only key"),
    ([{"matrix": [[1, 0, 0, 0]] * 3}], "4 rows of 4 numbers"),
    ([{"translate": [1, 10 ** 400, 3]}], "NaN or infinite"),
], ids=["empty", "object", "short", "string", "zero-axis", "no-angle", "unknown", "two-keys", "three-rows",
        "huge-int"])
def test_a_malformed_transform_names_the_entry(ops, problem):
    with pytest.raises(InputError, match=problem) as info:
        operations_from_json("shapes[2].transform", ops)
    assert str(info.value).startswith("shapes[2].transform")


# -- in a scene -------------------------------------------------------------------------------

@pytest.fixture
def box(tmp_path):
    folder = tmp_path / "box"
    shutil.copytree(CORNELL, folder, ignore=shutil.ignore_patterns("*.exr"))
    return folder


def edit(folder, change):
    data = json.loads((folder / "scene.json").read_text())
    change(data)
    (folder / "scene.json").write_text(json.dumps(data))


def test_a_mirrored_emitter_still_emits_downwards(box):
    # The light (a quad facing -y) mirrored through the plane z = 0 lands on itself, wound the other
    # way: re-wound, its normal is still A^-T (0, -1, 0) = (0, -1, 0).
    edit(box, lambda d: d["shapes"][LIGHT].__setitem__("transform", [{"scale": [1, 1, -1]}]))
    scene, original = load_scene(box), load_scene(CORNELL)
    lights = scene.light_triangles
    np.testing.assert_array_equal(face_normal(scene.vertices, scene.triangles[lights]),
                                  face_normal(original.vertices, original.triangles[original.light_triangles]))
    assert np.all(face_normal(scene.vertices, scene.triangles[lights])[:, 1] == -1)


def test_a_translated_shape_moves_and_the_others_stay(box):
    edit(box, lambda d: d["shapes"][LIGHT].__setitem__("transform", [{"translate": [0.25, -0.5, 0]}]))
    scene, original = load_scene(box), load_scene(CORNELL)
    moved = scene.vertices[scene.triangles[scene.light_triangles]]
    before = original.vertices[original.triangles[original.light_triangles]]
    np.testing.assert_array_equal(moved, before + [0.25, -0.5, 0])
    others = np.setdiff1d(np.arange(len(scene.triangles)), scene.light_triangles)
    assert np.array_equal(scene.vertices[scene.triangles[others]], original.vertices[original.triangles[others]])


def test_a_singular_transform_in_a_scene_names_the_shape_and_its_mesh(box):
    edit(box, lambda d: d["shapes"][2].__setitem__("transform", [{"scale": [2, 0, 2]}]))
    with pytest.raises(SceneError, match=r"shapes\[2\] \(meshes/\w+\.obj\): the transform is singular"):
        load_scene(box)


def test_the_camera_placed_by_look_at_is_the_camera_of_origin_target_up(box):
    def by_look_at(d):
        cam = d["camera"]
        cam["transform"] = [{"look_at": {k: cam.pop(k) for k in ("origin", "target", "up")}}]
    edit(box, by_look_at)
    scene, original = load_scene(box), load_scene(CORNELL)
    np.testing.assert_array_equal(scene.camera.origin, original.camera.origin)
    # The target is origin + the unit viewing direction: the same basis, to rounding.
    for ours, theirs in zip(scene.camera.basis(), original.camera.basis()):
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-15)


def test_a_camera_moved_after_its_look_at(box):
    edit(box, lambda d: d["camera"].update(transform=[
        {"look_at": {"origin": [0, 0, 0], "target": [0, 0, -1], "up": [0, 1, 0]}}, {"translate": [0, 0, 3.9]}])
        or [d["camera"].pop(k) for k in ("origin", "target", "up")])
    camera = load_scene(box).camera
    assert np.array_equal(camera.origin, [0, 0, 3.9]) and np.array_equal(camera.target, [0, 0, 2.9])


@pytest.mark.parametrize("ops", [[{"scale": [-1, 1, 1]}], [{"scale": [1, 2, 1]}]], ids=["mirror", "per-axis"])
def test_a_camera_transform_that_distorts_its_rays_is_refused(box, ops):
    edit(box, lambda d: d["camera"].update(transform=ops) or [d["camera"].pop(k) for k in ("origin", "target", "up")])
    with pytest.raises(SceneError, match="camera's transform may only rotate, translate and scale uniformly"):
        load_scene(box)


def test_a_camera_with_both_placements_is_refused(box):
    edit(box, lambda d: d["camera"].update(transform=[{"translate": [0, 0, 1]}]))
    with pytest.raises(SceneError, match="either by origin, target and up or by a transform"):
        load_scene(box)


def test_camera_frame_of_a_rotation():
    origin, target, up = camera_frame(rotate([0, 1, 0], 90), "camera")
    np.testing.assert_allclose(target - origin, [1, 0, 0], atol=1e-15)    # +z turned to +x
    np.testing.assert_allclose(up, [0, 1, 0], atol=1e-15)
