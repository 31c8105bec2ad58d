"""Mesh files by their suffix: OBJ through the toolkit's own strict reader (obj.py), PLY, GLB/glTF,
STL and OFF through trimesh (scenes/FORMAT.md, "Meshes").

A mesh file is untrusted input. Before trimesh reads one, what it would allocate is checked: a
PLY header's counts against the scene's limits and the file's size (ply_header.py), an STL's
triangle count, an OFF's counts, the size of the text formats, whose parsing takes many times
their size in memory. trimesh gets the bytes, never a path, so no file the mesh names (a
texture, a glTF buffer) is ever opened. What it reads is checked again: faces that index past
the vertices, NaN or infinite coordinates, no faces at all. Each problem is an InputError that
names the file.

What a file holds that the toolkit does not model (normals, colours, UVs, textures, materials)
is returned in words, for the loader to name once in a warning.
"""
import io
import json
import struct
from pathlib import Path

import numpy as np

from toolkit.core.errors import InputError
from toolkit.core.obj import read_obj
from toolkit.core.ply_header import PlyHeader
from toolkit.core.validate import LIMITS, in_range

TRIMESH_TYPES = {".ply": "ply", ".glb": "glb", ".gltf": "gltf", ".stl": "stl", ".off": "off"}
SUFFIXES = (".obj", *TRIMESH_TYPES)
# glTF's mesh attributes beyond POSITION, in words.
GLTF_ATTRIBUTES = {"NORMAL": "normals", "TANGENT": "tangents", "TEXCOORD": "UVs", "COLOR": "vertex colours",
                   "JOINTS": "skinning", "WEIGHTS": "skinning"}


def read_mesh(path, earlier_vertices=0, earlier_triangles=0):
    """(vertices float64 (N, 3), triangles int64 (M, 3), what the file holds that is not modelled).
    The earlier counts are the scene's other meshes', so that the scene's limits hold for all."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".obj":
        unmodelled = set()
        vertices, triangles = read_obj(path, earlier_vertices, earlier_triangles, unmodelled)
        return vertices, triangles, sorted(unmodelled)
    if suffix not in TRIMESH_TYPES:
        raise InputError(f"{path}: unknown mesh type {suffix or '(no suffix)'!r}; the toolkit reads "
                         f"{', '.join(SUFFIXES)}")
    try:
        data = path.read_bytes()        # its size is within LIMITS["mesh.bytes"] (checked by the loader)
    except FileNotFoundError:
        raise InputError(f"{path}: mesh file not found") from None
    except OSError as error:
        raise InputError(f"{path}: cannot read mesh: {error}") from None
    rooms = (LIMITS["scene.vertices"][1] - earlier_vertices, LIMITS["scene.triangles"][1] - earlier_triangles)
    kind = TRIMESH_TYPES[suffix]
    unmodelled = PRECHECKS[kind](path, data, *rooms)
    vertices, triangles = _checked(path, *_trimesh_read(path, data, kind), *rooms)
    return vertices, triangles, unmodelled


def _trimesh_read(path, data, kind):
    import trimesh         # here, not at the top: its import takes half a second, and OBJ scenes never need it
    try:
        if kind in ("glb", "gltf"):
            # A glTF is a scene: force="mesh" joins its meshes, each through its node's transform;
            # process=False, maintain_order=True: no merged vertices, no reordered faces.
            mesh = trimesh.load(io.BytesIO(data), file_type=kind, force="mesh", process=False, maintain_order=True,
                                skip_materials=True)
            vertices, faces = mesh.vertices, mesh.faces
        else:
            # trimesh's parser of the format alone: its arrays as the file has them, without the
            # Trimesh object (whose making took 9 of the 10 parts of the memory and time of a
            # 2-million-triangle PLY). No resolver: no file the mesh names is opened.
            loaded = trimesh.exchange.load.mesh_loaders[kind](io.BytesIO(data), file_type=kind, fix_texture=False)
            vertices, faces = loaded.get("vertices"), loaded.get("faces")
        vertices = np.asarray(vertices if vertices is not None else np.zeros((0, 3)), np.float64)
        faces = _fans(np.asarray(faces if faces is not None else np.zeros((0, 3)), np.int64))
    # trimesh's parsers raise whatever the bad bytes lead them to (ValueError, IndexError,
    # KeyError, struct.error, ...): any of them means this file cannot be read as `kind`.
    except Exception as error:       # noqa: BLE001 -- a third-party parser on untrusted bytes
        raise InputError(f"{path}: not a readable {kind.upper()} file ({type(error).__name__}: "
                         f"{str(error)[:120] or 'no detail'})") from None
    return vertices, faces


def _fans(faces):
    """Polygons of k > 3 corners (a PLY of quads comes back from trimesh's parser unsplit) as fans
    from their first corner, face by face, as the OBJ reader splits them: the same triangles."""
    if faces.ndim != 2 or faces.shape[1] <= 3:
        return faces
    k = faces.shape[1]
    return np.stack([np.repeat(faces[:, :1], k - 2, 1), faces[:, 1:-1], faces[:, 2:]], axis=2).reshape(-1, 3)


def _checked(path, vertices, faces, vertex_room, triangle_room):
    """The arrays trimesh read, as the scene needs them; an InputError naming the file otherwise."""
    if faces.size == 0:
        raise InputError(f"{path}: mesh has no faces")
    if vertices.ndim != 2 or vertices.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3:
        raise InputError(f"{path}: expected 3-D vertices and triangles, got arrays of shape {vertices.shape} "
                         f"and {faces.shape}")
    if len(vertices) > vertex_room:
        in_range("scene.vertices", LIMITS["scene.vertices"][1] - vertex_room + len(vertices),
                 f"{path}: the scene's vertex count")
    if len(faces) > triangle_room:
        in_range("scene.triangles", LIMITS["scene.triangles"][1] - triangle_room + len(faces),
                 f"{path}: the scene's triangle count")
    outside = (faces < 0) | (faces >= len(vertices))
    if outside.any():
        face = int(np.flatnonzero(outside.any(1))[0])
        raise InputError(f"{path}: face {face} indexes vertex {int(faces[face][outside[face]][0])}, "
                         f"but the file has {len(vertices)} vertices (0 to {len(vertices) - 1})")
    bad = ~np.isfinite(vertices).all(1)
    if bad.any():
        raise InputError(f"{path}: vertex {int(np.flatnonzero(bad)[0])} has a NaN or infinite coordinate "
                         f"({int(bad.sum())} such vertices)")
    return vertices, faces


# -- what each format is checked for before trimesh reads it -----------------------------------

def _text_size(path, data):
    in_range("mesh.text_bytes", max(len(data), 1), f"{path}: size of a text mesh file (bytes)")


def _ply(path, data, vertex_room, triangle_room):
    header = PlyHeader(data, path)
    if header.ascii:
        _text_size(path, data)
    header.check(vertex_room, triangle_room)
    return header.unmodelled()


def _stl(path, data, vertex_room, triangle_room):
    if len(data) >= 84:
        count, = struct.unpack_from("<I", data, 80)
        if len(data) == 84 + 50 * count:    # binary: 80 bytes, a count, 50 bytes a triangle
            if count > min(triangle_room, vertex_room // 3):
                raise InputError(f"{path}: the STL file has {count} triangles, more than the scene has room for")
            return []                          # its facet normals are the winding's (FORMAT.md)
    if not data.lstrip()[:5].lower() == b"solid":
        raise InputError(f"{path}: not an STL file (neither 'solid ...' text nor a binary STL whose "
                         "triangle count matches its size)")
    _text_size(path, data)
    return []


def _off(path, data, vertex_room, triangle_room):
    _text_size(path, data)
    words = []
    for line in data[:4096].split(b"\n"):
        words += line.split(b"#", 1)[0].split()
        if len(words) >= 3:
            break
    if not words or words[0] not in (b"OFF", b"COFF"):
        raise InputError(f"{path}: not an OFF file (it must start with OFF or COFF; "
                         f"{words[0][:10].decode('ascii', 'replace') if words else 'it is empty'!r} found)")
    try:
        vertices, faces = int(words[1]), int(words[2])
    except (IndexError, ValueError):
        raise InputError(f"{path}: the OFF file's second line must give its vertex and face counts") from None
    # At least "0 0 0\n" a vertex and "3 0 1 2\n" a face.
    if vertices > vertex_room or faces > triangle_room or vertices * 6 + faces * 8 > len(data):
        raise InputError(f"{path}: the OFF header claims {vertices} vertices and {faces} faces: more than the "
                         f"file's {len(data)} bytes can hold, or than the scene has room for")
    return ["vertex colours"] if words[0] == b"COFF" else []


def _glb(path, data, vertex_room, triangle_room):
    if len(data) < 20 or data[:4] != b"glTF":
        raise InputError(f"{path}: not a GLB file (it does not start with 'glTF')")
    version, length, chunk_length, chunk_type = struct.unpack_from("<III4s", data, 4)
    if version != 2 or length != len(data) or chunk_type != b"JSON" or 20 + chunk_length > len(data):
        raise InputError(f"{path}: not a GLB 2.0 file whose header matches its size ({len(data)} bytes)")
    return _gltf_json(path, data[20:20 + chunk_length], vertex_room, triangle_room)


def _gltf(path, data, vertex_room, triangle_room):
    _text_size(path, data)
    return _gltf_json(path, data, vertex_room, triangle_room)


def _gltf_json(path, text, vertex_room, triangle_room):
    try:
        document = json.loads(text)
    except (ValueError, RecursionError) as error:
        raise InputError(f"{path}: not a glTF file (its JSON: {str(error)[:80]})") from None
    if not isinstance(document, dict) or not isinstance(document.get("asset"), dict):
        raise InputError(f"{path}: not a glTF file (no 'asset' object)")
    try:
        vertices, triangles = _gltf_counts(document)
    except (TypeError, KeyError, IndexError, ValueError, AttributeError) as error:
        raise InputError(f"{path}: not a valid glTF file (its meshes, accessors or nodes: "
                         f"{type(error).__name__} {str(error)[:60]})") from None
    if vertices > vertex_room or triangles > triangle_room:
        raise InputError(f"{path}: the glTF file's meshes, each as often as its nodes place it, make {vertices} "
                         f"vertices and {triangles} triangles: more than the scene has room for ({vertex_room} "
                         f"vertices, {triangle_room} triangles)")
    for buffer in _list(document, "buffers") + _list(document, "images"):
        uri = buffer.get("uri") if isinstance(buffer, dict) else None
        if uri is not None and not (isinstance(uri, str) and uri.startswith("data:")):
            raise InputError(f"{path}: the glTF file refers to another file ({str(uri)[:60]!r}); the toolkit reads "
                             f"no file a mesh names: use a .glb or embed the buffers as data: URIs")
    found = set()
    for mesh in _list(document, "meshes"):
        for primitive in _list(mesh, "primitives"):
            attributes = primitive.get("attributes", {}) if isinstance(primitive, dict) else {}
            for name in attributes if isinstance(attributes, dict) else ():
                found.update(v for k, v in GLTF_ATTRIBUTES.items() if name.startswith(k))
            if isinstance(primitive, dict) and primitive.get("mode", 4) != 4:
                found.add("points or lines (only triangles are read)")
    found.update(key for key in ("materials", "textures", "cameras", "animations", "skins") if _list(document, key))
    if "KHR_lights_punctual" in str(document.get("extensionsUsed", "")):
        found.add("lights")
    return sorted(found)


def _gltf_counts(document):
    """(vertices, triangles) that joining the glTF's meshes makes: each mesh as many times as the
    nodes of its scene place it (a file of a few MB can place one big mesh a million times)."""
    accessors = _list(document, "accessors")
    meshes = []
    for mesh in _list(document, "meshes"):
        v = t = 0
        for primitive in _list(mesh, "primitives"):
            positions = accessors[primitive["attributes"]["POSITION"]]["count"]
            v += int(positions)
            if primitive.get("mode", 4) == 4:
                t += int(accessors[primitive["indices"]]["count"] if "indices" in primitive else positions) // 3
        meshes.append((v, t))
    nodes = _list(document, "nodes")
    scenes = _list(document, "scenes")
    # The default scene's nodes; with no scene, every node may be shown.
    roots = list(scenes[document.get("scene", 0)].get("nodes", [])) if scenes else list(range(len(nodes)))
    # Each node the scene reaches, once (trimesh places a node once, however often it is listed).
    reached, stack = set(), roots
    while stack:
        k = int(stack.pop())
        if k not in reached:
            reached.add(k)
            stack.extend(nodes[k].get("children", []))
    placed = [meshes[nodes[k]["mesh"]] for k in reached if "mesh" in nodes[k]] if nodes else meshes
    return sum(v for v, _ in placed), sum(t for _, t in placed)


def _list(document, key):
    value = document.get(key, []) if isinstance(document, dict) else []
    return value if isinstance(value, list) else []


PRECHECKS = {"ply": _ply, "stl": _stl, "off": _off, "glb": _glb, "gltf": _gltf}
