"""A minimal OBJ reader for the interchange format: `v` and `f` lines only (FORMAT.md)."""
import numpy as np


class ObjError(ValueError):
    pass


def read_obj(path):
    """(vertices float64 (N,3), triangles int64 (M,3), zero-based). Polygons become fans."""
    try:
        text = open(path, encoding="utf-8").read()
    except FileNotFoundError:
        raise ObjError(f"{path}: mesh file not found") from None
    except (OSError, UnicodeDecodeError) as error:
        raise ObjError(f"{path}: cannot read mesh: {error}") from None
    vertices, triangles = [], []
    for number, line in enumerate(text.splitlines(), start=1):
        fields = line.split("#", 1)[0].split()
        if not fields:
            continue
        if fields[0] == "v":
            try:
                xyz = [float(x) for x in fields[1:4]]
            except ValueError:
                raise ObjError(f"{path}:{number}: vertex has a non-number: {line.strip()!r}") from None
            if len(xyz) != 3:
                raise ObjError(f"{path}:{number}: vertex needs 3 coordinates: {line.strip()!r}")
            if not all(np.isfinite(xyz)):
                raise ObjError(f"{path}:{number}: vertex coordinate is NaN or infinite: {line.strip()!r}")
            vertices.append(xyz)
        elif fields[0] == "f":
            try:
                # "7/2/3" keeps only the position index; negative indices count from the end.
                ids = [int(f.split("/")[0]) for f in fields[1:]]
            except ValueError:
                raise ObjError(f"{path}:{number}: face index is not an integer: {line.strip()!r}") from None
            if len(ids) < 3:
                raise ObjError(f"{path}:{number}: face needs at least 3 vertices: {line.strip()!r}")
            for i in ids:  # 1..n, or -n..-1 counting back from the last vertex; 0 is invalid
                if not (1 <= i <= len(vertices) or -len(vertices) <= i <= -1):
                    raise ObjError(f"{path}:{number}: face index {i} out of range "
                                   f"(the file has {len(vertices)} vertices so far)")
            ids = [i - 1 if i > 0 else len(vertices) + i for i in ids]
            for k in range(1, len(ids) - 1):
                triangles.append((ids[0], ids[k], ids[k + 1]))
        # vn, vt, o, g, s, usemtl ... are ignored by the format.
    if not triangles:
        raise ObjError(f"{path}: mesh has no faces")
    return np.asarray(vertices, np.float64), np.asarray(triangles, np.int64)
