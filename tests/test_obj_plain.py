"""The OBJ reader's quick path (toolkit/core/obj_plain.py): on a plain file it gives the line
reader's arrays bit for bit, and on anything else it answers None, so that the line reader reads
the file (the same arrays, or the same error naming the line)."""
from pathlib import Path

import numpy as np
import pytest

from toolkit.core import obj
from toolkit.core.obj import ObjError, read_obj
from toolkit.core.obj_plain import read_plain_obj
from toolkit.core.validate import LIMITS

ROOMS = (LIMITS["mesh.line_length"][1], LIMITS["scene.vertices"][1], LIMITS["scene.triangles"][1])


def line_reader(path, monkeypatch):
    """read_obj with the quick path turned off: the reader as it was before."""
    with monkeypatch.context() as patch:
        patch.setattr(obj, "read_plain_obj", lambda *args: None)
        return read_obj(path)


def write(tmp_path, text, name="mesh.obj"):
    path = tmp_path / name
    path.write_bytes(text.encode() if isinstance(text, str) else text)
    return path


def plain_text(seed=7, vertices=300, faces=500):
    """Numbers written in every way a float can be written in OBJ text: shortest repr, %.17g,
    exponents of either case, a leading + or ., a trailing ., tabs, blank lines, a header."""
    rng = np.random.default_rng(seed)
    v = rng.normal(scale=10.0 ** rng.integers(-30, 30, (vertices, 1)), size=(vertices, 3))
    forms = [repr, "{:.17g}".format, "{:.9g}".format, "{:E}".format, lambda x: f"+{x:.6f}" if x >= 0 else f"{x:.6f}",
             lambda x: f"{x:.3f}".replace("0.", ".", 1) if 0 <= x < 1 else repr(x), lambda x: f"{round(x)}."]
    lines = ["# a header comment: ünïcödé", "", "# another"]
    for k, xyz in enumerate(v):
        numbers = [forms[(k + i) % len(forms)](float(x)) for i, x in enumerate(xyz)]
        lines.append(("v\t" if k % 11 == 0 else "v ") + ("  " if k % 5 == 0 else " ").join(numbers))
        if k % 17 == 0:
            lines.append("")
    f = rng.integers(1, vertices + 1, (faces, 3))
    lines += [f"f {a} {b}\t{c}" + ("  " if k % 3 == 0 else "") for k, (a, b, c) in enumerate(f)]
    return "\n".join(lines)          # no newline after the last line


def test_a_plain_file_gives_the_line_reader_s_arrays_bit_for_bit(tmp_path, monkeypatch):
    text = plain_text().replace("v\t", "v ")     # 'v' and a tab is for the line reader (below)
    path = write(tmp_path, text)
    quick = read_plain_obj(path, *ROOMS)
    assert quick is not None, "a plain file must take the quick path"
    expected = line_reader(path, monkeypatch)
    for got, want in zip(quick, expected):
        assert got.dtype == want.dtype and got.shape == want.shape
        assert np.array_equal(got.view(np.uint8), want.view(np.uint8))      # bits, not values
    assert all(np.array_equal(a, b) for a, b in zip(read_obj(path), expected))


def test_bundled_meshes_take_the_quick_path_with_the_same_arrays(monkeypatch):
    from toolkit.core.scene import bundled_scene_dir
    for path in sorted(bundled_scene_dir("cornell_spheres").glob("meshes/*.obj")):
        quick = read_plain_obj(path, *ROOMS)
        assert quick is not None, path
        assert all(np.array_equal(a, b) for a, b in zip(quick, line_reader(path, monkeypatch))), path


# Files the quick path must leave to the line reader: each is read as before, or refused as before.
NOT_PLAIN = {
    "a vertex after the faces": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nv 0 0 1\nf 1 2 4\n",
    "a quad": "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n",
    "a quad among triangles": "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 2 3 4\n",
    "slashes": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2/2 3/3\n",
    "negative indices": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n",
    "CR LF": "v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3\r\n",
    "a lone CR in the header": "# x\rv 9 9 9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    "a comment among vertices": "v 0 0 0\n# x\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    "a comment after a face": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 # x\n",
    "normals": "v 0 0 0\nvn 0 0 1\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    "a w coordinate": "v 0 0 0 1\nv 1 0 0 1\nv 0 1 0 1\nf 1 2 3\n",
    "'v1' is not a vertex": "v 0 0 0\nv1 5 5 5\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    "a line of numbers alone": "v 0 0 0\n7 7 7\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    "an object name": "o thing\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    # Refused by the line reader, each naming its line:
    "two coordinates": "v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n",
    "a NaN": "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n",
    "an overflow to infinity": "v 0 0 0\nv 1e999 0 0\nv 0 1 0\nf 1 2 3\n",
    "a number that is not one": "v 0 0 0\nv 1.2.3 0 0\nv 0 1 0\nf 1 2 3\n",
    "a lone minus": "v 0 0 0\nv - 0 0\nv 0 1 0\nf 1 2 3\n",
    "index 0": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
    "an index past the vertices": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
    "a vertex letter alone": "v 0 0 0\nv\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    "a face of two": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n",
    "a huge index": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999999\n",
    "no faces": "v 0 0 0\nv 1 0 0\nv 0 1 0\n",
    "not UTF-8 in the header": b"# \xff\xfe\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
}


@pytest.mark.parametrize("case", NOT_PLAIN)
def test_what_is_not_plain_is_left_to_the_line_reader(tmp_path, monkeypatch, case):
    path = write(tmp_path, NOT_PLAIN[case])
    assert read_plain_obj(path, *ROOMS) is None
    try:
        expected = line_reader(path, monkeypatch)
    except ObjError as error:
        with pytest.raises(ObjError) as raised:
            read_obj(path)
        assert str(raised.value) == str(error)
    else:
        assert all(np.array_equal(a, b) for a, b in zip(read_obj(path), expected))


def test_a_line_over_the_length_limit_is_left_to_the_line_reader(tmp_path, monkeypatch):
    path = write(tmp_path, "v 0 0 0\nv 1 0 0\nv 0 1 0" + " " * 100 + "\nf 1 2 3\n")
    assert read_plain_obj(path, 50, *ROOMS[1:]) is None
    monkeypatch.setitem(LIMITS, "mesh.line_length", (0, 50, LIMITS["mesh.line_length"][2]))
    with pytest.raises(Exception, match="line length"):
        read_obj(path)


def test_a_scene_s_vertex_and_triangle_rooms_are_left_to_the_line_reader(tmp_path):
    path = write(tmp_path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 3 2\n")
    assert read_plain_obj(path, ROOMS[0], 3, 2) is not None
    assert read_plain_obj(path, ROOMS[0], 2, 2) is None
    assert read_plain_obj(path, ROOMS[0], 3, 1) is None
    with pytest.raises(Exception, match="triangle count"):
        read_obj(path, earlier_triangles=LIMITS["scene.triangles"][1] - 1)


def test_a_small_file_is_read_without_reserving_the_size_limit(tmp_path):
    """The quick path once read with file.read(PLAIN_MAX_BYTES + 1), which allocates 512 MB before
    it reads: a grader's worker, under a 0.8 GB data limit, failed to build every kernel with a
    MemoryError. Under a data limit of 64 MB above what the process uses, a small file still reads."""
    import subprocess
    import sys
    pytest.importorskip("resource")      # POSIX's data limit
    path = tmp_path / "box.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    code = ("import resource, sys\n"
            "from toolkit.core.obj_plain import read_plain_obj\n"
            "used = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024\n"
            "limit = used + 64 * 2**20\n"
            "resource.setrlimit(resource.RLIMIT_DATA, (limit, limit))\n"
            "v, t = read_plain_obj(sys.argv[1], 4096, 10, 10)\n"
            "print(len(v), len(t))\n")
    root = Path(__file__).resolve().parent.parent
    run = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=120,
                         cwd=root)
    assert run.returncode == 0 and run.stdout.split() == ["3", "1"], run.stderr
