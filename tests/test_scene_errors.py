"""Bad scenes fail early with a SceneError that names the file (and line) and the problem.

Every bad scene is a copy of scenes/cornell_box in tmp_path with one thing broken, so each
test shows exactly which input the loader rejects. The last tests run the CLI on bad scenes:
exit code 2 and one `error: ...` line, no traceback.
"""
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from toolkit.core.scene import SceneError, load_scene

ROOT = Path(__file__).resolve().parent.parent
CORNELL = ROOT / "scenes" / "cornell_box"
FLOOR = "meshes/floor.obj"      # shapes[0], material "white"
LIGHT = "meshes/light.obj"      # shapes[7], the only emitter


@pytest.fixture
def box(tmp_path):
    """A private copy of the Cornell box (without the reference images: not needed here)."""
    folder = tmp_path / "box"
    shutil.copytree(CORNELL, folder, ignore=shutil.ignore_patterns("*.exr"))
    return folder


def read_json(folder):
    return json.loads((folder / "scene.json").read_text())


def write_json(folder, data):
    (folder / "scene.json").write_text(json.dumps(data, indent=2))


def edit_json(folder, change):
    data = read_json(folder)
    change(data)
    write_json(folder, data)


def write_obj(folder, mesh, text):
    (folder / mesh).write_text(text)


def load_fails(path, *fragments):
    """load_scene(path) raises SceneError whose message holds every fragment; returns it."""
    with pytest.raises(SceneError) as info:
        load_scene(path)
    message = str(info.value)
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"
    return message


def json_file(folder):
    return str(folder / "scene.json")


def obj_at(folder, mesh, line):
    return f"{folder / mesh}:{line}:"


def test_the_unmodified_copy_loads(box):
    scene = load_scene(box)
    assert scene.dropped_triangles == 0
    assert len(scene.light_triangles) == 2


# -- files and JSON ---------------------------------------------------------------------------

def test_missing_scene_folder_is_reported_by_path(tmp_path):
    load_fails(tmp_path / "nowhere", str(tmp_path / "nowhere"), "not found")


def test_folder_without_scene_json_names_the_missing_file(tmp_path):
    load_fails(tmp_path, str(tmp_path / "scene.json"), "not found")


def test_missing_scene_file_is_reported_by_path(tmp_path):
    load_fails(tmp_path / "other.json", str(tmp_path / "other.json"), "not found")


def test_malformed_json_names_line_and_column(box):
    text = (box / "scene.json").read_text().splitlines()
    line = next(i for i, t in enumerate(text, 1) if '"fov_axis"' in t)
    text[line - 1] = text[line - 1].rstrip(",")   # a missing comma
    (box / "scene.json").write_text("\n".join(text))
    message = load_fails(box, "malformed JSON")
    assert message.startswith(f"{json_file(box)}:{line + 1}:"), message


def test_json_top_level_must_be_an_object(box):
    (box / "scene.json").write_text("[1, 2, 3]")
    load_fails(box, json_file(box), "top level must be a JSON object")


def test_scene_file_not_utf8_is_reported_unreadable(box):
    (box / "scene.json").write_bytes(b'{"format": "\xff\xfe"}')
    load_fails(box, json_file(box), "cannot read")


@pytest.mark.parametrize("value", ["toolkit-scene/2", None])
def test_wrong_or_missing_format_is_refused(box, value):
    def change(d):
        if value is None:
            del d["format"]
        else:
            d["format"] = value
    edit_json(box, change)
    load_fails(box, json_file(box), "'format' must be 'toolkit-scene/1'", repr(value))


@pytest.mark.parametrize("key", ["origin", "target", "up", "fov_deg", "width", "height"])
def test_missing_camera_key_is_named(box, key):
    edit_json(box, lambda d: d["camera"].pop(key))
    load_fails(box, json_file(box), f"camera has no '{key}'")


def test_missing_camera_is_refused(box):
    edit_json(box, lambda d: d.pop("camera"))
    load_fails(box, json_file(box), "'camera' must be an object")


@pytest.mark.parametrize("field,where", [("origin", "camera.origin"), ("up", "camera.up")])
def test_nan_literal_in_json_vector_is_refused_with_its_field(box, field, where):
    edit_json(box, lambda d: d["camera"].__setitem__(field, [float("nan"), 0.0, 3.9]))
    assert "NaN" in (box / "scene.json").read_text()   # Python's json writes and reads this literal
    load_fails(box, json_file(box), where, "NaN or infinite")


def test_infinity_literal_in_emission_is_refused_with_its_shape(box):
    edit_json(box, lambda d: d["shapes"][7].__setitem__("emission", [math.inf, 1.0, 1.0]))
    assert "Infinity" in (box / "scene.json").read_text()
    load_fails(box, json_file(box), "shapes[7].emission", "NaN or infinite")


def test_nan_literal_in_json_number_is_refused_with_its_field(box):
    edit_json(box, lambda d: d["camera"].__setitem__("fov_deg", float("nan")))
    load_fails(box, json_file(box), "camera.fov_deg", "finite number")


def test_nan_in_reflectance_is_refused_with_its_material(box):
    edit_json(box, lambda d: d["materials"]["red"].__setitem__("reflectance", [0.5, float("nan"), 0.5]))
    load_fails(box, json_file(box), "material 'red'.reflectance", "NaN or infinite")


# -- materials and shapes ---------------------------------------------------------------------

def test_unknown_material_type_is_refused_listing_the_known_ones(box):
    edit_json(box, lambda d: d["materials"]["red"].__setitem__("type", "velvet"))
    load_fails(box, json_file(box), "material 'red'", "unknown type 'velvet'", "diffuse")


def test_shape_with_unknown_material_is_refused(box):
    edit_json(box, lambda d: d["shapes"][3].__setitem__("material", "blue"))
    load_fails(box, json_file(box), "shapes[3]", "unknown material 'blue'")


def test_shape_mesh_must_be_a_string(box):
    edit_json(box, lambda d: d["shapes"][0].__setitem__("mesh", 5))
    load_fails(box, json_file(box), "shapes[0]", "must be strings")


def test_negative_reflectance_is_refused(box):
    edit_json(box, lambda d: d["materials"]["green"].__setitem__("reflectance", [0.1, -0.2, 0.1]))
    load_fails(box, json_file(box), "material 'green'.reflectance", "negative value")


def test_reflectance_above_one_is_refused(box):
    edit_json(box, lambda d: d["materials"]["green"].__setitem__("reflectance", [0.1, 1.2, 0.1]))
    load_fails(box, json_file(box), "material 'green'", "reflectance above 1")


def add_material(folder, name, material):
    """Add a material and put it on the large box (shapes[6])."""
    def change(d):
        d["materials"][name] = material
        d["shapes"][6]["material"] = name
    edit_json(folder, change)


@pytest.mark.parametrize("ior", [1.0, 0.5, -1.5])
def test_dielectric_ior_must_be_above_one(box, ior):
    add_material(box, "glass", {"type": "dielectric", "ior": ior})
    load_fails(box, json_file(box), "material 'glass'.ior", repr(ior), "outside")


def test_dielectric_without_ior_is_refused(box):
    add_material(box, "glass", {"type": "dielectric"})
    load_fails(box, json_file(box), "material 'glass' (dielectric) is missing ior")


def test_dielectric_with_ior_loads_and_is_compiled_in(box):
    add_material(box, "glass", {"type": "dielectric", "ior": 1.5})
    assert load_scene(box).features()["HAS_DIELECTRIC"]


def test_glossy_without_alpha_is_refused(box):
    add_material(box, "metal", {"type": "glossy", "reflectance": [0.9, 0.9, 0.9]})
    load_fails(box, json_file(box), "material 'metal' (glossy) is missing alpha")


# -- lights -----------------------------------------------------------------------------------

def test_scene_without_emission_is_refused_as_black(box):
    edit_json(box, lambda d: d["shapes"][7].pop("emission"))
    load_fails(box, json_file(box), "no lights", "render black")


def test_all_zero_emission_is_refused_as_black(box):
    edit_json(box, lambda d: d["shapes"][7].__setitem__("emission", [0, 0, 0]))
    load_fails(box, json_file(box), "no lights", "render black")


# -- meshes -----------------------------------------------------------------------------------

def test_missing_mesh_file_is_named_with_its_shape(box):
    (box / FLOOR).unlink()
    load_fails(box, json_file(box), "shapes[0]", str(box / FLOOR), "mesh file not found")


QUAD = "# a quad\nv -1 -1 1\nv 1 -1 1\nv 1 -1 -1\nv -1 -1 -1\n"


@pytest.mark.parametrize("text,line,problem", [
    ("# a quad\nv -1 -1 1\nv 1 oops 1\nv 1 -1 -1\nf 1 2 3\n", 3, "non-number"),
    ("# a quad\nv -1 -1 1\nv 1 -1\nv 1 -1 -1\nf 1 2 3\n", 3, "needs 3 coordinates"),
    (QUAD + "f 1 2\n", 6, "at least 3 vertices"),
    (QUAD + "f 1 2 3\nf 1 2.5 3\n", 7, "not an integer"),
    (QUAD + "f 1 x 3\n", 6, "not an integer"),
    (QUAD + "f 1 2 5\n", 6, "face index 5 out of range"),
    (QUAD + "f 1 2 0\n", 6, "face index 0 out of range"),
    (QUAD + "f -1 -2 -5\n", 6, "face index -5 out of range"),
    ("v -1 -1 1\nv nan -1 1\nv 1 -1 -1\nf 1 2 3\n", 2, "NaN or infinite"),
    ("v -1 -1 1\nv 1 -1 inf\nv 1 -1 -1\nf 1 2 3\n", 2, "NaN or infinite"),
    ("v -1 -1 1\nv 1 -1 1\nv 1e999 -1 -1\nf 1 2 3\n", 3, "NaN or infinite"),
], ids=["non-number", "two-coordinates", "two-vertex-face", "float-index", "word-index",
        "index-too-large", "index-zero", "negative-index-too-far", "nan", "inf", "overflow"])
def test_malformed_obj_is_refused_naming_file_line_and_problem(box, text, line, problem):
    write_obj(box, FLOOR, text)
    load_fails(box, json_file(box), "shapes[0]", obj_at(box, FLOOR, line), problem)


def test_obj_without_faces_is_refused(box):
    write_obj(box, FLOOR, QUAD)
    load_fails(box, str(box / FLOOR), "no faces")


def test_negative_face_indices_are_valid(box):
    write_obj(box, FLOOR, QUAD + "f -4 -3 -2\nf -4 -2 -1\n")
    scene = load_scene(box)
    reference = load_scene(CORNELL)
    np.testing.assert_array_equal(scene.triangles, reference.triangles)


# -- degenerate triangles ---------------------------------------------------------------------

def test_degenerate_triangles_dropped_with_warning(box):
    # Two good triangles, a repeated vertex, three collinear points (a needle).
    write_obj(box, FLOOR, QUAD + "v 0 -1 1\nf 1 2 3\nf 1 3 4\nf 1 1 3\nf 1 5 2\n")
    with pytest.warns(UserWarning, match=r"dropped 2 degenerate"):
        scene = load_scene(box)
    assert scene.dropped_triangles == 2
    assert len(scene.triangles) == len(load_scene(CORNELL).triangles)
    assert len(scene.material_of) == len(scene.emission_of) == len(scene.triangles)


def test_all_degenerate_triangles_are_refused(box):
    data = read_json(box)
    data["shapes"] = [{"mesh": LIGHT, "material": "white", "emission": [1, 1, 1]}]
    write_json(box, data)
    write_obj(box, LIGHT, "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n")
    load_fails(box, json_file(box), "every triangle is degenerate")


def test_degenerate_light_leaves_no_lights(box):
    write_obj(box, LIGHT, "v 0 0.99 0\nv 0.2 0.99 0\nv 0.4 0.99 0\nf 1 2 3\n")
    with pytest.warns(UserWarning, match="dropped 1 degenerate"):
        load_fails(box, json_file(box), "no lights")


# -- the command line -------------------------------------------------------------------------

def run_cli(*args, cwd=ROOT):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    return subprocess.run([sys.executable, "-m", "toolkit", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("breakage", ["missing-scene", "bad-obj", "nan-json"])
def test_cli_render_of_a_bad_scene_exits_2_with_one_error_line(box, breakage):
    if breakage == "missing-scene":
        target, named = box / "nope", str(box / "nope")
    elif breakage == "bad-obj":
        write_obj(box, FLOOR, QUAD + "f 1 2 9\n")
        target, named = box, obj_at(box, FLOOR, 6)
    else:
        edit_json(box, lambda d: d["camera"].__setitem__("target", [0, float("nan"), 0]))
        target, named = box / "scene.json", json_file(box)
    result = run_cli("render", str(target), "--spp", "1", "--resolution", "8x8",
                     "--out", str(box / "out.exr"))
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    errors = [line for line in result.stderr.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1, result.stderr
    assert named in errors[0], errors[0]
    assert not (box / "out.exr").exists()


# -- a bundled scene by its name, in every command --------------------------------------------

def test_a_bundled_scene_loads_by_its_name_from_any_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert load_scene("covered_lamp").path.resolve() == (ROOT / "scenes" / "covered_lamp" / "scene.json").resolve()


def test_a_folder_of_that_name_here_wins_over_the_bundled_scene(tmp_path, monkeypatch):
    shutil.copytree(CORNELL, tmp_path / "covered_lamp", ignore=shutil.ignore_patterns("*.exr"))
    monkeypatch.chdir(tmp_path)
    assert len(load_scene("covered_lamp").triangles) == len(load_scene(CORNELL).triangles)


def test_an_unknown_name_lists_the_bundled_scenes(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    load_fails("cornell_bx", "cornell_bx: no such scene folder or scene file", "cornell_box, cornell_bunny, cornell_spheres")


def test_cli_render_takes_a_bundled_scene_s_name(tmp_path):
    """Before: `render cornell_spheres` said "scene file not found" while `demo cornell_spheres` worked."""
    result = run_cli("render", "cornell_spheres", "--spp", "1", "--resolution", "8x8", "--technique", "pt_naive",
                     "--out", str(tmp_path / "out.exr"), cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "out.exr").is_file()
