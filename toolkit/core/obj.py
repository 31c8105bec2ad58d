"""A minimal OBJ reader for the interchange format: `v` and `f` lines only (FORMAT.md).

It reads the file line by line (each line up to its length limit) into compact arrays (8 bytes
a number) and stops at the scene's vertex and triangle limits as it goes: a file is untrusted,
and lists of Python numbers built before the limits were checked reached 67 times the file's
size in memory."""
import math
from array import array

import numpy as np

from toolkit.core.obj_plain import read_plain_obj
from toolkit.core.validate import LIMITS, in_range


class ObjError(ValueError):
    pass


# Lines the format ignores that carry what the toolkit does not model, in words (the loader names them).
UNMODELLED = {"vn": "normals", "vt": "UVs", "usemtl": "materials", "mtllib": "materials"}


def read_obj(path, earlier_vertices=0, earlier_triangles=0, unmodelled=None):
    """(vertices float64 (N,3), triangles int64 (M,3), zero-based). Polygons become fans.
    `earlier_vertices` / `earlier_triangles`: the counts of the scene's other meshes read before,
    so that LIMITS["scene.vertices"] and ["scene.triangles"] hold for the whole scene (an
    InputError naming the line where a limit was passed). `unmodelled`: a set that gets the
    words for the ignored lines that carry normals, UVs or materials."""
    vertices, triangles = array("d"), array("q")
    longest = LIMITS["mesh.line_length"][1]
    # Room left in the scene; the error is made (with its line) only when a limit is passed.
    vertex_room = LIMITS["scene.vertices"][1] - earlier_vertices
    triangle_room = LIMITS["scene.triangles"][1] - earlier_triangles
    # A plain file (only v and f lines) is parsed by numpy at once, four times as fast; any
    # other file, or one with something wrong in it, line by line below.
    plain = read_plain_obj(path, longest, vertex_room, triangle_room)
    if plain is not None:
        return plain
    try:
        with open(path, encoding="utf-8") as file:
            # A line is read up to its limit, not whole: one line can be the whole file.
            for number, line in enumerate(iter(lambda: file.readline(longest + 2), ""), start=1):
                if len(line) > longest and len(line.rstrip("\r\n")) > longest:
                    in_range("mesh.line_length", len(line.rstrip("\r\n")), f"{path}:{number}: line length (characters)")
                fields = line.split("#", 1)[0].split()
                if not fields:
                    continue
                if fields[0] == "v":
                    vertices.extend(_vertex(path, number, fields, line))
                    if len(vertices) > 3 * vertex_room:
                        _stopped("scene.vertices", earlier_vertices + len(vertices) // 3, path, number, "vertex")
                elif fields[0] == "f":
                    if len(triangles) // 3 + len(fields) - 3 > triangle_room:
                        _stopped("scene.triangles", earlier_triangles + len(triangles) // 3 + len(fields) - 3, path,
                                 number, "triangle")
                    triangles.extend(_fan(path, number, fields, line, len(vertices) // 3))
                elif unmodelled is not None and fields[0] in UNMODELLED:
                    unmodelled.add(UNMODELLED[fields[0]])
                # vn, vt, o, g, s, usemtl ... are ignored by the format.
    except FileNotFoundError:
        raise ObjError(f"{path}: mesh file not found") from None
    except (OSError, UnicodeDecodeError) as error:
        raise ObjError(f"{path}: cannot read mesh: {error}") from None
    if not triangles:
        raise ObjError(f"{path}: mesh has no faces")
    return np.frombuffer(vertices, np.float64).reshape(-1, 3), np.frombuffer(triangles, np.int64).reshape(-1, 3)


def _stopped(limit, count, path, number, what):
    in_range(limit, count, f"{path}:{number}: the scene's {what} count (the reader stopped here)")


# Each line's parsing has a quick path for the common case ("v x y z", "f a b c" with indices in
# range) and the careful one, which says what is wrong, for everything else: the same results,
# in a third of the time (a mesh of a million triangles has a million and a half lines).

def _vertex(path, number, fields, line):
    if len(fields) >= 4:
        try:
            x, y, z = float(fields[1]), float(fields[2]), float(fields[3])
        except ValueError:
            pass
        else:
            if math.isfinite(x) and math.isfinite(y) and math.isfinite(z):
                return x, y, z
    where = f"{path}:{number}"
    try:
        xyz = [float(x) for x in fields[1:4]]
    except ValueError:
        raise ObjError(f"{where}: vertex has a non-number: {line.strip()!r}") from None
    if len(xyz) != 3:
        raise ObjError(f"{where}: vertex needs 3 coordinates: {line.strip()!r}")
    if not all(np.isfinite(xyz)):
        raise ObjError(f"{where}: vertex coordinate is NaN or infinite: {line.strip()!r}")
    return xyz


def _fan(path, number, fields, line, count):
    """The triangles (flat, zero-based) of one face line over the `count` vertices read so far."""
    if len(fields) == 4:
        try:
            a, b, c = int(fields[1]), int(fields[2]), int(fields[3])
        except ValueError:      # "7/2/3" and the like: the careful path
            pass
        else:
            if 1 <= a <= count and 1 <= b <= count and 1 <= c <= count:
                return a - 1, b - 1, c - 1
    where = f"{path}:{number}"
    try:
        # "7/2/3" keeps only the position index; negative indices count from the end.
        ids = [int(f.split("/")[0]) for f in fields[1:]]
    except ValueError:
        raise ObjError(f"{where}: face index is not an integer: {line.strip()!r}") from None
    if len(ids) < 3:
        raise ObjError(f"{where}: face needs at least 3 vertices: {line.strip()!r}")
    for i in ids:  # 1..n, or -n..-1 counting back from the last vertex; 0 is invalid
        if not (1 <= i <= count or -count <= i <= -1):
            raise ObjError(f"{where}: face index {i} out of range (the file has {count} vertices so far)")
    ids = [i - 1 if i > 0 else count + i for i in ids]
    return [v for k in range(1, len(ids) - 1) for v in (ids[0], ids[k], ids[k + 1])]
