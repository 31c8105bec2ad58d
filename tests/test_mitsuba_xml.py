"""Mitsuba 3's XML as a scene (toolkit/core/mitsuba_xml.py, mitsuba_scene.py; scenes/FORMAT.md,
"Mitsuba 3 XML"): the round trip through the writer in toolkit/peers/mitsuba.py, renders compared
with Mitsuba 3 on the same file, the subset's edges and hostile files.

Mitsuba's own Cornell box and documentation scenes (the mitsuba-data repository, which states no
licence, so they are not copied here) are tested where MITSUBA_DATA names a checkout of it.
"""
import math
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from toolkit.core import analytic_shapes
from toolkit.core.scene import SceneError, bundled_scene_names, load_scene
from toolkit.core.transforms import compose
from toolkit.measure.reference import z_test
from toolkit.peers.mitsuba import write_mitsuba_xml

FIXTURES = Path(__file__).parent / "fixtures" / "mitsuba"
MITSUBA_DATA = os.environ.get("MITSUBA_DATA")
ROOT = Path(__file__).parent.parent


def _load(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_scene(path)


# -- the round trip: a bundled scene written by peers/mitsuba.py reads back as the same scene --------

def _canonical(scene):
    """Each triangle as (its vertices in float32, its material, its emission), sorted: the same
    scene whatever order or vertex sharing a writer chose."""
    v = scene.vertices.astype(np.float32)[scene.triangles]
    rows = []
    for tri, m, e in zip(v, scene.material_of, scene.emission_of):
        material = scene.materials[m]
        k = min(range(3), key=lambda i: tuple(tri[i]))       # rotate the corners: the winding is kept
        corners = tuple(map(tuple, np.roll(tri, -k, axis=0)))
        rows.append((corners, material["type"], tuple(material["reflectance"]), material["ior"],
                     material["alpha"], tuple(e)))
    return sorted(rows)


@pytest.mark.parametrize("name", bundled_scene_names())
def test_round_trip_gives_the_same_scene(name, tmp_path):
    scene = _load(name)
    back = _load(write_mitsuba_xml(scene, tmp_path))
    assert _canonical(back) == _canonical(scene)
    for a, b in zip(back.camera.basis(), scene.camera.basis()):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(back.camera.origin, scene.camera.origin)
    assert (back.camera.fov_deg, back.camera.fov_axis, back.camera.width, back.camera.height) == \
        (scene.camera.fov_deg, scene.camera.fov_axis, scene.camera.width, scene.camera.height)
    assert (back.max_depth, back.rr_depth) == (scene.max_depth, scene.rr_depth)


def test_round_trip_keeps_no_roulette(tmp_path):
    """rr_depth -1 is written as a depth no path reaches; it reads back as -1."""
    scene = _load("cornell_box")
    scene.max_depth, scene.rr_depth = 4, -1
    back = _load(write_mitsuba_xml(scene, tmp_path))
    assert (back.max_depth, back.rr_depth) == (4, -1)


# -- the same file rendered by Mitsuba 3 and by the toolkit ---------------------------------------

def _compare_with_mitsuba(path, res, spp, toolkit_spp, passes=16):
    """(z-test of the toolkit's render against Mitsuba's mean of `passes` renders, the same test
    with the toolkit's image 5% darker: it must fail, or the comparison could not see an error)."""
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    from toolkit.api import render
    scene = mi.load_file(str(path), res=res)      # both files take their resolution from $res
    images = np.stack([np.array(mi.render(scene, spp=spp, seed=k))[..., :3] for k in range(passes)])
    ref, ref_err = images.mean(0), images.std(0, ddof=1) / math.sqrt(passes)
    ours = render(_load(path), technique="pt_naive", spp=toolkit_spp, seed=1, resolution=(res, res))
    test = z_test(ours.image, ours.stderr, ref, ref_err, alpha=0.01, dof=ours.stats["degrees_of_freedom"])
    darker = z_test(0.95 * ours.image, ours.stderr, ref, ref_err, alpha=0.01, dof=ours.stats["degrees_of_freedom"])
    return test, darker


def test_scene_with_every_element_agrees_with_mitsuba():
    test, darker = _compare_with_mitsuba(FIXTURES / "every_element" / "scene.xml", 16, 512, 2048)
    assert test.passed, str(test)
    assert not darker.passed, str(darker)


@pytest.mark.skipif(not MITSUBA_DATA, reason="MITSUBA_DATA names no checkout of mitsuba-data (not bundled: "
                                             "the repository states no licence)")
def test_mitsubas_cornell_box_agrees_with_mitsuba():
    test, darker = _compare_with_mitsuba(Path(MITSUBA_DATA) / "scenes" / "cbox" / "cbox-rgb.xml", 16, 256, 1024)
    assert test.passed, str(test)
    assert not darker.passed, str(darker)


# -- refused: the element, its file:line, exit 2 and no traceback ----------------------------------

def _render_cli(path):
    return subprocess.run([sys.executable, "-m", "toolkit", "render", str(path), "--spp", "1"], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("name, element, line", [("plastic.xml", "<bsdf 'plastic'>", 3),
                                                 ("envmap.xml", "<emitter 'envmap'>", 6),
                                                 ("bitmap.xml", "<texture 'bitmap'>", 5)])
def test_unsupported_features_are_refused_by_name_and_line(name, element, line):
    result = _render_cli(FIXTURES / "unsupported" / name)
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert f"{name}:{line}: {element} is not in the subset" in result.stderr
    assert "Supported: shapes obj, ply" in result.stderr


@pytest.mark.skipif(not MITSUBA_DATA, reason="MITSUBA_DATA names no checkout of mitsuba-data")
@pytest.mark.parametrize("name, element", [
    ("bsdf_plastic_default.xml", "bsdf_plastic_default.xml:4: <bsdf 'plastic'>"),
    ("bsdf_diffuse_textured.xml", "matpreview.xml:9: <shape 'serialized'>"),
    ("integrator_depth_2.xml", "integrator_depth_2.xml:46: <spectrum 'reflectance'>")])
def test_mitsubas_documentation_scenes_are_refused(name, element):
    result = _render_cli(Path(MITSUBA_DATA) / "docs" / "scenes" / name)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert element in result.stderr


def _scene(tmp_path, body, sensor=None, name="scene.xml"):
    """A small scene file: `body` with a light and a camera unless `sensor` replaces the camera."""
    sensor = sensor if sensor is not None else """
        <sensor type="perspective"><float name="fov" value="40"/>
            <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
            <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
        </sensor>"""
    path = tmp_path / name
    path.write_text(f"""<scene version="3.0.0">{sensor}
        <shape type="rectangle"><emitter type="area"><rgb name="radiance" value="1, 1, 1"/></emitter></shape>
        {body}
    </scene>""")
    return path


@pytest.mark.parametrize("body, message", [
    ('<bsdf type="conductor" id="c"><string name="material" value="Au"/></bsdf>'
     '<shape type="cube"><ref id="c"/></shape>', "material 'Au'"),
    ('<shape type="cube"><bsdf type="roughconductor"/></shape>', "distribution 'beckmann'"),
    ('<shape type="cube"><bsdf type="dielectric"/></shape>', "ext_ior is 1.000277"),
    ('<shape type="cube"><bsdf type="diffuse"><float name="roughness" value="1"/></bsdf></shape>',
     "property 'roughness'"),
    ('<shape type="cube"><ref id="nothing"/></shape>', "names no element"),
    ('<shape type="cube"><float name="radius" value="2"/></shape>', "property 'radius'"),
    ('<emitter type="area"><rgb name="radiance" value="1"/></emitter>', "must be inside a <shape>"),
    ('<shape type="cube"><transform name="to_world"><scale value="0"/></transform></shape>', "singular"),
    ('<shape type="cube"><integer name="x" value="$undefined"/></shape>', "$undefined has no value"),
])
def test_outside_the_subset_is_an_error_naming_the_line(tmp_path, body, message):
    with pytest.raises(SceneError, match=r"scene\.xml:\d+: .*") as error:
        _load(_scene(tmp_path, body))
    assert message in str(error.value)


def test_clipping_planes_only_where_they_clip_nothing(tmp_path):
    sensor = """<sensor type="perspective"><float name="fov" value="40"/><float name="{}" value="{}"/>
        <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0"/></transform></sensor>"""
    _load(_scene(tmp_path, "", sensor.format("near_clip", 4.5)))          # the rectangle is 5 away
    with pytest.raises(SceneError, match="near_clip 5.5 may clip"):
        _load(_scene(tmp_path, "", sensor.format("near_clip", 5.5)))
    with pytest.raises(SceneError, match="far_clip 4.5 clips"):
        _load(_scene(tmp_path, "", sensor.format("far_clip", 4.5)))


def test_fov_axes_are_converted_to_the_same_camera(tmp_path):
    sensor = """<sensor type="perspective"><float name="fov" value="40"/><string name="fov_axis" value="{}"/>
        <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="40"/><integer name="height" value="30"/></film></sensor>"""
    cams = {axis: _load(_scene(tmp_path, "", sensor.format(axis))).camera for axis in
            ("x", "y", "smaller", "larger", "diagonal")}
    assert cams["smaller"].fov_axis == "y" and cams["larger"].fov_axis == "x"
    _, right, _ = cams["diagonal"].basis()
    assert np.linalg.norm(right) == pytest.approx(math.tan(math.radians(20)) * 40 / 50)   # tan(d/2) w / diagonal


def test_transforms_map_to_the_toolkits(tmp_path):
    """Each spelling of each operation against toolkit/core/transforms.py's matrices, composed
    in the order written (Mitsuba's)."""
    body = """<shape type="rectangle"><transform name="to_world">
        <scale x="2" y="3"/> <scale value="0.5"/> <rotate value="0, 0, 1" angle="90"/> <rotate x="1" angle="30"/>
        <translate value="1, 2, 3"/> <translate z="-1"/>
        <matrix value="1 0 0 0.5  0 1 0 0  0 0 1 0  0 0 0 1"/></transform><bsdf type="diffuse"/></shape>"""
    scene = _load(_scene(tmp_path, body))
    expected = compose([("scale", [2, 3, 1]), ("scale", [0.5] * 3), ("rotate", [0, 0, 1], 90),
                        ("rotate", [1, 0, 0], 30), ("translate", [1, 2, 3]), ("translate", [0, 0, -1]),
                        ("matrix", np.array([[1, 0, 0, .5], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.]]))])
    corners = analytic_shapes.rectangle()[0]
    np.testing.assert_allclose(scene.vertices[4:], corners @ expected[:3, :3].T + expected[:3, 3], atol=1e-12)


def test_analytic_shapes_to_their_stated_accuracy():
    for name, area in (("rectangle", 4.0), ("cube", 24.0)):
        v, t = analytic_shapes.SHAPES[name]()
        cross = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
        assert 0.5 * np.linalg.norm(cross, axis=1).sum() == pytest.approx(area)
    v, t = analytic_shapes.sphere()
    w = np.stack(np.meshgrid(np.linspace(0, 1, 21), np.linspace(0, 1, 21)), -1).reshape(-1, 2)
    w = w[w.sum(1) <= 1]
    points = v[t[:, 0]][:, None] + w[:, :1] * (v[t[:, 1]] - v[t[:, 0]])[:, None] + \
        w[:, 1:] * (v[t[:, 2]] - v[t[:, 0]])[:, None]
    depth = 1 - np.linalg.norm(points, axis=2)
    assert 0 <= depth.min() and depth.max() <= analytic_shapes.SPHERE_ERROR + 1e-12
    assert depth.max() > 0.9 * analytic_shapes.SPHERE_ERROR         # the stated bound is the actual one
    cross = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    assert np.all(np.einsum("ij,ij->i", cross, v[t].mean(1)) > 0)     # normals outward
    v, t = analytic_shapes.disk()
    edge_middles = 0.5 * (v[t[:, 1]] + v[t[:, 2]])
    assert 1 - np.linalg.norm(edge_middles, axis=1).min() == pytest.approx(analytic_shapes.DISK_ERROR)
    assert np.all(np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])[:, 2] > 0)     # normal +z


def test_curved_mesh_without_face_normals_is_named(tmp_path):
    """Mitsuba interpolates a mesh's normals unless face_normals is true; the toolkit cannot."""
    (tmp_path / "tetra.obj").write_text((FIXTURES / "every_element" / "parts" / "tetra.obj").read_text())
    with pytest.warns(UserWarning, match="face_normals"):
        load_scene(_scene(tmp_path, '<shape type="obj"><string name="filename" value="tetra.obj"/></shape>'))


# -- hostile files ---------------------------------------------------------------------------------

@pytest.mark.parametrize("text, message", [
    ('<scene version="3.0.0">\n<shape type="cube">\n</scene>', r"scene\.xml:3: malformed XML: mismatched tag"),
    ("", "XML read for this scene"),
    ('<?xml version="1.0"?>\n<!DOCTYPE scene [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">'
     '<!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;">]>\n<scene><string name="x" value="&c;"/></scene>', "refused XML"),
    ('<?xml version="1.0"?>\n<!DOCTYPE scene [<!ENTITY e SYSTEM "file:///etc/passwd">]>\n<scene>&e;</scene>',
     "refused XML"),
    ("<scene>" + "<shape>" * 100 + "</shape>" * 100 + "</scene>", "element nesting depth"),
    ('<scene><include filename="scene.xml"/></scene>', "include cycle: scene.xml includes scene.xml"),
    ('<scene><include filename="../outside.xml"/></scene>', "must be inside the scene folder"),
    ('<shape type="cube"/>', "root element must be <scene>"),
    # Not the format its name says: a scene.json, and a mesh's bytes, named scene.xml.
    ((ROOT / "scenes" / "cornell_box" / "scene.json").read_text(), r"scene\.xml:1: malformed XML: not well-formed"),
    ("ply\nformat binary_little_endian 1.0\nelement vertex 3\nend_header\n\x00\x80", r"scene\.xml:1: malformed XML"),
])
def test_hostile_xml_is_refused(tmp_path, text, message):
    path = tmp_path / "scene.xml"
    path.write_text(text)
    with pytest.raises(SceneError, match=message):
        _load(path)


@pytest.mark.parametrize("body, line, element", [
    ('<shape type="cube"><transform name="to_world"><translate value="nan 0 0"/></transform></shape>', 7,
     "<translate>"),
    ('<shape type="cube"><transform name="to_world"><scale value="1e999"/></transform></shape>', 7, "<scale>"),
    ('<shape type="disk"><emitter type="area"><rgb name="radiance" value="1, inf, 1"/></emitter></shape>', 7,
     "<rgb 'radiance'>"),
    ('<shape type="sphere"><point name="center" x="0" y="-inf" z="0"/></shape>', 7, "<point 'center'>"),
], ids=["translate-nan", "scale-overflow", "radiance-inf", "center-inf"])
def test_nan_or_infinite_numbers_are_refused_naming_the_element(tmp_path, body, line, element):
    with pytest.raises(SceneError, match=rf"scene\.xml:{line}: NaN or infinite value in {element}"):
        _load(_scene(tmp_path, body))


def test_a_nan_field_of_view_is_refused_naming_the_element(tmp_path):
    sensor = '<sensor type="perspective"><float name="fov" value="NaN"/></sensor>'
    with pytest.raises(SceneError, match=r"scene\.xml:1: NaN or infinite value in <float 'fov'>"):
        _load(_scene(tmp_path, '<shape type="cube"/>', sensor=sensor))


def test_include_cycle_through_two_files_and_include_depth(tmp_path):
    (tmp_path / "a.xml").write_text('<scene><include filename="b.xml"/></scene>')
    (tmp_path / "b.xml").write_text('<scene>\n<include filename="a.xml"/></scene>')
    with pytest.raises(SceneError, match=r"b\.xml:2: include cycle: a\.xml includes b\.xml includes a\.xml"):
        _load(tmp_path / "a.xml")
    for k in range(40):
        (tmp_path / f"n{k}.xml").write_text(f'<scene><include filename="n{k + 1}.xml"/></scene>')
    with pytest.raises(SceneError, match="include nesting depth"):
        _load(tmp_path / "n0.xml")


def test_includes_that_fan_out_are_bounded_by_files_parsed(tmp_path):
    """Each file includes the next twice: 2^16 parses of a small file, refused after 4,096 (before this
    bound, the byte budget refused it after 35,000 parses and 24 s)."""
    for k in range(16):
        (tmp_path / f"f{k}.xml").write_text(f'<scene>{"<!--" + "x" * 400 + "-->"}<include filename="f{k + 1}.xml"/>'
                                            f'<include filename="f{k + 1}.xml"/></scene>')
    (tmp_path / "f16.xml").write_text("<scene/>")
    with pytest.raises(SceneError, match="XML files parsed for this scene"):
        _load(tmp_path / "f0.xml")


def test_includes_of_large_files_are_bounded_by_bytes(tmp_path):
    """A 9 MB file included twice: 18 MB of XML, past the 16 MB read for one scene."""
    (tmp_path / "big.xml").write_text("<scene><!--" + "x" * (9 << 20) + "--></scene>")
    (tmp_path / "main.xml").write_text('<scene><include filename="big.xml"/><include filename="big.xml"/></scene>')
    with pytest.raises(SceneError, match="XML read for this scene"):
        _load(tmp_path / "main.xml")


def test_hostile_xml_on_the_command_line_exits_2_without_traceback(tmp_path):
    path = tmp_path / "bomb.xml"
    path.write_text('<!DOCTYPE s [<!ENTITY a "a"><!ENTITY b "&a;&a;">]>\n<scene>&b;</scene>')
    result = _render_cli(path)
    assert result.returncode == 2 and "Traceback" not in result.stderr and "bomb.xml" in result.stderr
