"""Meshes in PLY, GLB/glTF, STL and OFF (toolkit/core/mesh_files.py, through trimesh).

The same mesh gives the same image in every format (bit for bit, at a fixed seed); what a file
holds that the toolkit does not model is named once in a warning; and a hostile or broken mesh
file is an error that names the file and the problem (exit 2 on the command line), checked
before trimesh allocates what a header claims.
"""
import io
import json
import shutil
import struct
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh

import toolkit
from toolkit.core.scene import SceneError, load_scene

ROOT = Path(__file__).resolve().parent.parent
SPHERES = ROOT / "scenes" / "cornell_spheres"
CORNELL = ROOT / "scenes" / "cornell_box"
FLOOR = "meshes/floor.obj"      # shapes[0] of the Cornell box


def copy_of(scene, tmp_path):
    folder = tmp_path / scene.name
    shutil.copytree(scene, folder, ignore=shutil.ignore_patterns("*.exr"))
    return folder


def use_mesh(folder, old, new):
    """Point every shape of `folder` that uses mesh `old` to `new`."""
    data = json.loads((folder / "scene.json").read_text())
    for shape in data["shapes"]:
        if shape["mesh"] == old:
            shape["mesh"] = new
    (folder / "scene.json").write_text(json.dumps(data))


# -- each format, the same image --------------------------------------------------------------

def float32_exact_sphere(folder):
    """The glass sphere of cornell_spheres with coordinates rounded to float32 (GLB and STL store
    float32), written back as OBJ with every digit: the one mesh every format can hold exactly."""
    v, f = [], []
    for line in (SPHERES / "meshes" / "glass_sphere.obj").read_text().splitlines():
        if line.startswith("v "):
            v.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("f "):
            f.append([int(x) - 1 for x in line.split()[1:4]])
    v = np.array(v, np.float32).astype(np.float64)
    (folder / "meshes" / "glass_sphere.obj").write_text(
        "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in v.tolist())
        + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f))
    return trimesh.Trimesh(v, np.array(f), process=False)


@pytest.fixture(scope="module")
def sphere_scene(tmp_path_factory):
    folder = copy_of(SPHERES, tmp_path_factory.mktemp("formats"))
    mesh = float32_exact_sphere(folder)
    for suffix in ("ply", "glb", "stl"):
        mesh.export(folder / "meshes" / f"glass_sphere.{suffix}")
    # OFF is text in fixed point: 60 decimals give 17 significant digits down to 1e-43, so every
    # coordinate (a float32, > 1e-38 or 0) reads back exactly.
    (folder / "meshes" / "glass_sphere.off").write_text(trimesh.exchange.off.export_off(mesh, digits=60))
    return folder


def render_with(folder, mesh):
    use_mesh(folder, next(m for m in ("meshes/glass_sphere.obj", *(f"meshes/glass_sphere.{s}" for s in
                                                                      ("ply", "glb", "stl", "off")))
                          if m in (folder / "scene.json").read_text()), mesh)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")     # a format's unmodelled parts: tested below
        scene = load_scene(folder)
    result = toolkit.render(scene, technique="pt_naive", spp=2, seed=11, resolution=(12, 12), count_simd=False)
    return scene, result.image


def test_every_format_gives_the_obj_mesh_s_image_bit_for_bit(sphere_scene):
    obj_scene, obj_image = render_with(sphere_scene, "meshes/glass_sphere.obj")
    assert obj_image.mean() > 0
    for suffix in ("ply", "glb", "stl", "off"):
        scene, image = render_with(sphere_scene, f"meshes/glass_sphere.{suffix}")
        # The same triangles, corner for corner, in the same order (STL keeps 3 vertices a triangle).
        assert np.array_equal(scene.vertices[scene.triangles], obj_scene.vertices[obj_scene.triangles]), suffix
        assert image.tobytes() == obj_image.tobytes(), f"{suffix}: the image differs from the OBJ mesh's"


# -- what the toolkit does not model, named once ----------------------------------------------

def ply_text(vertex_props, rows, faces, extra=""):
    head = "".join(f"property float {p}\n" for p in vertex_props)
    return (f"ply\nformat ascii 1.0\n{extra}element vertex {len(rows)}\n{head}element face {len(faces)}\n"
            "property list uchar int vertex_indices\nend_header\n"
            + "".join(" ".join(map(str, r)) + "\n" for r in rows)
            + "".join(f"{len(f)} {' '.join(map(str, f))}\n" for f in faces))


FLOOR_ROWS = [(-1, -1, 1), (1, -1, 1), (1, -1, -1), (-1, -1, -1)]   # the Cornell box's floor, as floor.obj


def test_a_ply_quad_is_the_obj_floor_and_its_normals_and_colours_are_named_once(tmp_path):
    box = copy_of(CORNELL, tmp_path)
    rows = [(*p, 0, 1, 0, 0.5, 0.5, 0.5) for p in FLOOR_ROWS]
    (box / "meshes" / "floor.ply").write_text(
        ply_text(["x", "y", "z", "nx", "ny", "nz", "red", "green", "blue"], rows, [(0, 1, 2, 3)]))
    use_mesh(box, FLOOR, "meshes/floor.ply")
    with pytest.warns(UserWarning) as caught:
        scene = load_scene(box)
    unmodelled = [str(w.message) for w in caught if "does not model" in str(w.message)]
    assert len(unmodelled) == 1 and "meshes/floor.ply: vertex normals, vertex colours" in unmodelled[0], unmodelled
    reference = load_scene(CORNELL)
    # A polygon is a fan from its first corner, as in OBJ (FORMAT.md): the same triangles, corner for corner.
    assert np.array_equal(scene.vertices[scene.triangles], reference.vertices[reference.triangles])


def test_obj_normals_uvs_and_materials_are_named_in_a_warning(tmp_path):
    box = copy_of(CORNELL, tmp_path)
    text = (box / FLOOR).read_text()
    (box / FLOOR).write_text("mtllib box.mtl\nvn 0 1 0\nvt 0 0\nusemtl white\n" + text)
    with pytest.warns(UserWarning) as caught:
        load_scene(box)
    message, = [str(w.message) for w in caught]
    assert "does not model: meshes/floor.obj: " in message
    assert all(word in message for word in ("materials", "normals", "UVs")), message


def test_bundled_scenes_load_without_a_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for name in ("cornell_box", "cornell_bunny", "cornell_spheres", "covered_lamp", "door_ajar"):
            load_scene(name)


# -- hostile and broken files: an error naming the file and the problem -----------------------

def binary_ply(vertex_count, face_count, body):
    return (f"ply\nformat binary_little_endian 1.0\nelement vertex {vertex_count}\nproperty float x\n"
            f"property float y\nproperty float z\nelement face {face_count}\n"
            "property list uchar int vertex_indices\nend_header\n").encode() + body


def corners(*xyz):
    return struct.pack(f"<{len(xyz)}f", *xyz)


def face(*ids):
    return struct.pack(f"<B{len(ids)}i", len(ids), *ids)


TRIANGLE = corners(-1, -1, 1, 1, -1, 1, 1, -1, -1)


def fails_as(tmp_path, name, data, *fragments):
    box = copy_of(CORNELL, tmp_path)
    (box / "meshes" / name).write_bytes(data)
    use_mesh(box, FLOOR, f"meshes/{name}")
    with pytest.raises(SceneError) as info:
        load_scene(box)
    message = str(info.value)
    for fragment in (f"meshes/{name}", *fragments):
        assert fragment in message, f"{fragment!r} not in {message!r}"
    return box


@pytest.mark.parametrize("vertices,faces,problem", [
    (3_000_000_000, 1, "claims 3000000000 vertices, more than the scene has room for"),
    (3, 4_000_000_000, "claims 4000000000 faces, more than the scene has room for"),
    # Within the limits, but not within the file: 1,000,000 faces need 1 MB at least.
    (3, 1_000_000, "need at least 1000036 bytes, but the file has 49 after its header"),
], ids=["billions-of-vertices", "billions-of-faces", "more-than-the-file-holds"])
def test_a_ply_header_that_claims_too_much_is_refused_before_reading(tmp_path, vertices, faces, problem):
    fails_as(tmp_path, "huge.ply", binary_ply(vertices, faces, TRIANGLE + face(0, 1, 2)), problem)


def test_an_ascii_ply_header_that_claims_more_lines_than_the_file_has_is_refused(tmp_path):
    # trimesh reads the lines there are, and would silently make a mesh of them.
    data = ply_text(["x", "y", "z"], FLOOR_ROWS, [(0, 1, 2)]).replace("element vertex 4", "element vertex 2000000")
    fails_as(tmp_path, "short.ply", data.encode(), "claims 2000000 vertex", "bytes")


@pytest.mark.parametrize("name,data,problem", [
    ("past.ply", binary_ply(3, 1, TRIANGLE + face(0, 1, 7)), "face 0 indexes vertex 7, but the file has 3 vertices"),
    ("negative.ply", binary_ply(3, 1, TRIANGLE + face(0, -1, 2)), "face 0 indexes vertex -1"),
    ("past.off", b"OFF\n3 1 0\n-1 -1 1\n1 -1 1\n1 -1 -1\n3 0 1 5\n", "face index outside the range"),
], ids=["ply-past-the-end", "ply-negative", "off-past-the-end"])
def test_faces_that_index_past_the_vertices_are_refused(tmp_path, name, data, problem):
    fails_as(tmp_path, name, data, problem)


@pytest.mark.parametrize("name,data", [
    ("nan.ply", binary_ply(3, 1, corners(-1, -1, 1, float("nan"), -1, 1, 1, -1, -1) + face(0, 1, 2))),
    ("inf.ply", binary_ply(3, 1, corners(-1, -1, 1, 1, -1, float("inf"), 1, -1, -1) + face(0, 1, 2))),
    ("inf.off", b"OFF\n3 1 0\n-1 -1 1\n1 -1 inf\n1 -1 -1\n3 0 1 2\n"),
    ("nan.stl", trimesh.exchange.stl.export_stl(trimesh.Trimesh([[0, 0, 0], [1, np.nan, 0], [0, 1, 0]], [[0, 1, 2]],
                                                                process=False))),
], ids=["ply-nan", "ply-inf", "off-inf", "stl-nan"])
def test_nan_or_infinite_coordinates_are_refused(tmp_path, name, data):
    fails_as(tmp_path, name, data, "vertex 1 has a NaN or infinite coordinate")


@pytest.mark.parametrize("name,data,problem", [
    ("obj_text.ply", (CORNELL / FLOOR).read_bytes(), "not a PLY file"),
    ("text.glb", b'{"asset": {"version": "2.0"}}', "not a GLB file"),
    ("noise.stl", bytes(range(256)) * 3, "not an STL file"),
    ("obj_text.off", (CORNELL / FLOOR).read_bytes(), "not an OFF file"),
    ("ply_text.gltf", binary_ply(3, 1, TRIANGLE + face(0, 1, 2)), "not a glTF file"),
    ("floor.xyz", (CORNELL / FLOOR).read_bytes(), "unknown mesh type '.xyz'"),
    ("ply_bytes.obj", binary_ply(3, 1, TRIANGLE + face(0, 1, 2)), "cannot read mesh: 'utf-8' codec can't decode"),
], ids=["ply", "glb", "stl", "off", "gltf", "unknown-suffix", "obj"])
def test_a_file_that_is_not_the_format_its_name_says_is_refused(tmp_path, name, data, problem):
    fails_as(tmp_path, name, data, problem)


@pytest.mark.parametrize("name,data,problem", [
    ("empty.ply", binary_ply(0, 0, b""), "no faces"),
    ("points.ply", binary_ply(3, 0, TRIANGLE), "no faces"),
    ("empty.stl", b"\0" * 80 + struct.pack("<I", 0), "no faces"),
    ("empty.off", b"OFF\n0 0 0\n", "no faces"),
], ids=["ply", "ply-point-cloud", "stl", "off"])
def test_an_empty_mesh_is_refused(tmp_path, name, data, problem):
    fails_as(tmp_path, name, data, problem)


def test_a_text_mesh_over_its_size_limit_is_refused_before_parsing(tmp_path, monkeypatch):
    from toolkit.core.validate import LIMITS
    monkeypatch.setitem(LIMITS, "mesh.text_bytes", (1, 64, "test"))
    off = b"OFF\n3 1 0\n-1 -1 1\n1 -1 1\n1 -1 -1\n3 0 1 2\n" + b"# padding\n" * 4
    fails_as(tmp_path, "long.off", off, f"size of a text mesh file (bytes) {len(off)} is outside 1 .. 64")


def gltf_placing(floor_nodes):
    """The Cornell box's floor (2 triangles) as a glTF with embedded buffers, its mesh placed by the
    nodes `floor_nodes` makes (a list of glTF node objects; the scene shows node 0)."""
    import base64
    positions = np.array(FLOOR_ROWS, np.float32).tobytes()
    indices = np.array([0, 1, 2, 0, 2, 3], np.uint32).tobytes()
    data = "data:application/octet-stream;base64," + base64.b64encode(positions + indices).decode()
    return json.dumps({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": floor_nodes,
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"uri": data, "byteLength": 72}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                        {"buffer": 0, "byteOffset": 48, "byteLength": 24}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                       "min": [-1, -1, -1], "max": [1, -1, 1]},
                      {"bufferView": 1, "componentType": 5125, "count": 6, "type": "SCALAR"}]}).encode()


def test_a_gltf_with_embedded_buffers_is_the_obj_floor(tmp_path):
    box = copy_of(CORNELL, tmp_path)
    (box / "meshes" / "floor.gltf").write_bytes(gltf_placing([{"mesh": 0}]))
    use_mesh(box, FLOOR, "meshes/floor.gltf")
    scene, reference = load_scene(box), load_scene(CORNELL)
    assert np.array_equal(scene.vertices[scene.triangles], reference.vertices[reference.triangles])


def test_a_gltf_whose_nodes_place_a_mesh_too_often_is_refused_before_reading(tmp_path, monkeypatch):
    from toolkit.core.validate import LIMITS
    monkeypatch.setitem(LIMITS, "scene.triangles", (1, 1000, "test"))   # a file of a few KB, not of 100 MB
    nodes = [{"children": list(range(1, 502))}] + [{"mesh": 0}] * 501        # the floor 501 times: 1002 triangles
    fails_as(tmp_path, "many.gltf", gltf_placing(nodes), "more than the scene has room for")


def test_a_gltf_that_names_another_file_is_refused_and_the_file_is_not_read(tmp_path):
    document = {"asset": {"version": "2.0"}, "buffers": [{"uri": "../../secret.bin", "byteLength": 36}]}
    fails_as(tmp_path, "outside.gltf", json.dumps(document).encode(), "refers to another file", "secret.bin")


def test_the_command_line_says_one_line_and_exits_2(tmp_path):
    box = fails_as(tmp_path, "huge.ply", binary_ply(3_000_000_000, 1, TRIANGLE + face(0, 1, 2)), "claims")
    result = subprocess.run([sys.executable, "-m", "toolkit", "render", str(box), "--spp", "1", "--resolution", "8x8",
                             "--out", str(tmp_path / "out.exr")], capture_output=True, text=True, timeout=300,
                            cwd=ROOT)
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr and "huge.ply" in result.stderr and "claims" in result.stderr
