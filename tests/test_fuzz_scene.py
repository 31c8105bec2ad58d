"""Fuzz the scene loader with hypothesis: random, malformed scene.json documents, OBJ files,
PLY/STL/OFF/GLB files and transforms (250 examples a test, a few seconds each: every example is
a few small files). Each must load or raise the toolkit's own SceneError; any other exception
(or a hang: the loader reads only small regular files) is a bug. Random valid OBJ files must read
as a plain reading of FORMAT.md reads them. Examples are derandomized so a failure reproduces;
hypothesis prints the smallest failing example."""
import copy
import json
import os
import shutil
import tempfile
import warnings
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from toolkit.core.scene import SceneError, load_scene

CORNELL = Path(__file__).resolve().parent.parent / "scenes" / "cornell_box"
BASE = json.loads((CORNELL / "scene.json").read_text())
SETTINGS = settings(max_examples=250, deadline=None, derandomize=True, database=None,
                    suppress_health_check=list(HealthCheck))

# Values a user (or a broken tool) might put anywhere: every JSON type, extreme numbers, paths.
numbers = st.one_of(st.integers(-3, 70), st.integers(), st.sampled_from([2 ** 64, -2 ** 63, 10 ** 400]),
                    st.floats(), st.sampled_from([1e-46, 1e39, 1e-300, 1e300, -0.0, 0.5, 1.0]))
strings = st.one_of(st.text(max_size=12), st.sampled_from(
    ["x", "y", "diffuse", "glossy", "mirror", "dielectric", "white", "meshes/floor.obj", "/dev/zero",
     "../scene.json", "meshes", "", "meshes/pipe.obj", "toolkit-scene/1", "notes"]))
leaves = st.one_of(st.none(), st.booleans(), numbers, strings)
values = st.recursive(leaves, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                      st.dictionaries(strings, inner, max_size=4)), max_leaves=12)


def paths(doc, prefix=()):
    """Every (path) into a JSON document, the root included."""
    yield prefix
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from paths(v, prefix + (i,))


@st.composite
def mutated_scenes(draw):
    """The Cornell box's scene.json with 1-4 random edits: replace, delete or add a key anywhere."""
    doc = copy.deepcopy(BASE)
    rnd = draw(st.randoms())   # uniform over the document's places (sampled_from favours the first)
    for _ in range(draw(st.integers(1, 4))):
        where = rnd.choice(list(paths(doc)))
        if not where:
            continue
        parent = doc
        for p in where[:-1]:
            parent = parent[p]
        key, kind = where[-1], draw(st.sampled_from(["replace", "delete", "add"]))
        if kind == "replace":     # mostly a number or string where one was: deep into the checks
            parent[key] = draw(st.one_of(numbers, strings, values))
        elif kind == "delete":
            del parent[key]
        elif isinstance(parent, dict):
            parent[draw(strings)] = draw(values)
        else:
            parent.insert(key, draw(values))
    return json.dumps(doc)


@st.composite
def broken_texts(draw):
    """The scene.json text cut, with bytes inserted or deleted (malformed JSON and encodings)."""
    text = json.dumps(BASE).encode()
    i = draw(st.integers(0, len(text)))
    j = draw(st.integers(i, min(len(text), i + 20)))
    return text[:i] + draw(st.binary(max_size=8)) + text[j:]


token = st.one_of(numbers.map(str), st.sampled_from(["1/2/3", "-1", "0", "nan", "inf", "1e999", "//", "1//2", "x"]),
                  st.text(alphabet=st.characters(blacklist_categories=["Cs"]), max_size=5))
obj_line = st.one_of(
    st.tuples(st.just("v"), st.lists(token, max_size=4)), st.tuples(st.just("f"), st.lists(token, max_size=5)),
    st.tuples(st.sampled_from(["vn", "vt", "o", "g", "#", "usemtl", ""]), st.lists(token, max_size=3)),
    st.tuples(st.just("v"), st.lists(st.floats(-2, 2).map(repr), min_size=3, max_size=3)),
    st.tuples(st.just("f"), st.lists(st.integers(-6, 6).map(str), min_size=3, max_size=4))
).map(lambda line: " ".join([line[0], *line[1]]))
obj_files = st.lists(obj_line, max_size=12).map("\n".join)


@pytest.fixture(scope="module")
def folder():
    with tempfile.TemporaryDirectory() as tmp:
        box = Path(tmp) / "box"
        shutil.copytree(CORNELL, box, ignore=shutil.ignore_patterns("*.exr"))
        os.mkfifo(box / "meshes" / "pipe.obj")      # a mesh path may name it: must fail, not hang
        yield box


def loads_or_scene_error(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # dropped degenerate triangles
        try:
            load_scene(path)
        except SceneError as error:
            assert str(error) and "\n" not in str(error)


@SETTINGS
@given(text=mutated_scenes())
def test_mutated_scene_json(folder, text):
    (folder / "scene.json").write_text(text)
    loads_or_scene_error(folder)


@SETTINGS
@given(data=broken_texts())
def test_broken_scene_json_text(folder, data):
    (folder / "scene.json").write_bytes(data)
    loads_or_scene_error(folder)


@SETTINGS
@given(text=obj_files)
def test_random_obj_file(folder, text):
    (folder / "scene.json").write_text(json.dumps(BASE))
    (folder / "meshes" / "floor.obj").write_text(text, encoding="utf-8", errors="surrogatepass")
    loads_or_scene_error(folder)


# Mesh files through trimesh (toolkit/core/mesh_files.py): the Cornell box's floor as a small
# PLY, STL, OFF and GLB, its bytes cut, changed or added to; and transforms anywhere in a shape.
def _floor_files():
    import trimesh
    lines = (CORNELL / "meshes" / "floor.obj").read_text().splitlines()
    v = [[float(x) for x in l.split()[1:]] for l in lines if l.startswith("v ")]
    f = [[int(x) - 1 for x in l.split()[1:]] for l in lines if l.startswith("f ")]
    mesh = trimesh.Trimesh(v, f, process=False)
    files = {s: mesh.export(file_type=s) for s in ("ply", "stl", "glb")}
    files["off"] = trimesh.exchange.off.export_off(mesh)
    files["ascii.ply"] = trimesh.exchange.ply.export_ply(mesh, encoding="ascii")
    return {k: v.encode() if isinstance(v, str) else v for k, v in files.items()}


@st.composite
def broken_meshes(draw):
    suffix, data = draw(st.sampled_from(sorted(_floor_files().items())))
    for _ in range(draw(st.integers(1, 3))):
        i = draw(st.integers(0, len(data)))
        j = draw(st.integers(i, min(len(data), i + 8)))
        data = data[:i] + draw(st.one_of(st.binary(max_size=6), st.sampled_from(
            [b"nan", b"inf", b"-1", b"4294967295", b"99999999999", b"\xff\xff\xff\x7f", b"\n", b" "]))) + data[j:]
    return suffix.split(".")[-1], data


@SETTINGS
@given(mesh=broken_meshes())
def test_random_broken_mesh_file(folder, mesh):
    suffix, data = mesh
    doc = copy.deepcopy(BASE)
    doc["shapes"][0]["mesh"] = f"meshes/floor.{suffix}"
    (folder / "scene.json").write_text(json.dumps(doc))
    (folder / "meshes" / f"floor.{suffix}").write_bytes(data)
    loads_or_scene_error(folder)


vectors = st.lists(numbers, min_size=3, max_size=3)
operations = st.one_of(
    st.builds(lambda v: {"translate": v}, vectors), st.builds(lambda v: {"scale": v}, st.one_of(numbers, vectors)),
    st.builds(lambda a, d: {"rotate": {"axis": a, "angle_deg": d}}, vectors, numbers),
    st.builds(lambda m: {"matrix": m}, st.lists(st.lists(numbers, min_size=4, max_size=4), min_size=4, max_size=4)),
    st.builds(lambda o, t, u: {"look_at": {"origin": o, "target": t, "up": u}}, vectors, vectors, vectors),
    st.dictionaries(strings, values, max_size=2))
transforms = st.one_of(st.lists(operations, max_size=4), values)


@SETTINGS
@given(transform=transforms, on_camera=st.booleans())
def test_random_transform(folder, transform, on_camera):
    doc = copy.deepcopy(BASE)
    if on_camera:
        doc["camera"] = {k: v for k, v in doc["camera"].items() if k not in ("origin", "target", "up")}
        doc["camera"]["transform"] = transform
    else:
        doc["shapes"][0]["transform"] = transform
    (folder / "scene.json").write_text(json.dumps(doc))
    loads_or_scene_error(folder)


# The OBJ reader's quick path ("v x y z", "f a b c") and careful path (the rest) give what a plain
# reading of FORMAT.md gives: positions as float() reads them, faces as fans, 1-based or negative.
def _plain_obj(text):
    vertices, triangles = [], []
    for line in text.splitlines():
        fields = line.split("#", 1)[0].split()
        if fields and fields[0] == "v":
            vertices.append([float(x) for x in fields[1:4]])
        elif fields and fields[0] == "f":
            ids = [int(f.split("/")[0]) for f in fields[1:]]
            ids = [i - 1 if i > 0 else len(vertices) + i for i in ids]
            triangles += [[ids[0], ids[k], ids[k + 1]] for k in range(1, len(ids) - 1)]
    return vertices, triangles


@st.composite
def valid_objs(draw):
    count = draw(st.integers(3, 8))
    coordinate = st.one_of(st.floats(-1e300, 1e300, allow_nan=False).map(repr), st.integers(-10, 10).map(str),
                           st.sampled_from(["1e-320", "-0.0", "1_0"]))
    lines = [" ".join(["v", *draw(st.lists(coordinate, min_size=3, max_size=4))]) for _ in range(count)]
    corner = st.one_of(st.integers(1, count).map(str), st.integers(-count, -1).map(str),
                       st.integers(1, count).map(lambda i: f"{i}/1/1"), st.integers(1, count).map(lambda i: f"{i}//2"))
    lines += [" ".join(["f", *draw(st.lists(corner, min_size=3, max_size=6))]) for _ in range(draw(st.integers(1, 6)))]
    return "\n".join(draw(st.permutations(lines[:count])) + lines[count:]) + "\n"


@SETTINGS
@given(text=valid_objs())
def test_the_obj_reader_reads_what_the_format_says(tmp_path_factory, text):
    from toolkit.core.obj import read_obj
    path = tmp_path_factory.mktemp("obj") / "mesh.obj"
    path.write_text(text)
    vertices, triangles = read_obj(path)
    plain_vertices, plain_triangles = _plain_obj(text)
    assert vertices.tolist() == plain_vertices and triangles.tolist() == plain_triangles
