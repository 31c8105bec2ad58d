"""A PLY file's header, read and checked before trimesh reads the file.

trimesh allocates what the header claims: a header that says a billion faces would have it
reserve gigabytes for a file of a few bytes. So the counts are checked here first, against the
scene's limits and against the bytes the file really has (each element needs at least so many:
its scalar properties' sizes in a binary file, a digit and a space per property in ASCII).
The header also says what the file holds beyond positions and faces (normals, colours, UVs),
which the toolkit does not model: named, so that the loader can say it ignored them.
"""
from toolkit.core.errors import InputError

LONGEST_HEADER = 1 << 16        # bytes; real headers are a few hundred
SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
         "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}
FORMATS = ("ascii", "binary_little_endian", "binary_big_endian")
FACE_LISTS = ("vertex_indices", "vertex_index")
# What the toolkit does not model, by the properties that carry it.
MEANINGS = {"normals": {"nx", "ny", "nz"},
            "colours": {"red", "green", "blue", "alpha", "r", "g", "b", "a", "diffuse_red", "diffuse_green",
                        "diffuse_blue"},
            "UVs": {"u", "v", "s", "t", "texture_u", "texture_v", "texture_s", "texture_t", "texcoord"}}


class PlyHeader:
    """`elements`: [(name, count, [(property, size or ("list", count size, item size))])];
    `ascii`; `data_bytes`: the bytes after the header."""

    def __init__(self, data, path):
        self.path = path
        end = data.find(b"end_header", 0, LONGEST_HEADER)
        if not data.startswith((b"ply\n", b"ply\r\n")):
            raise InputError(f"{path}: not a PLY file (it does not start with the line 'ply')")
        if end < 0:
            raise InputError(f"{path}: the PLY header has no 'end_header' in its first {LONGEST_HEADER} bytes")
        newline = data.find(b"\n", end)
        self.data_bytes = len(data) - (newline + 1 if newline >= 0 else len(data))
        try:
            lines = data[:end].decode("ascii").splitlines()[1:]
        except UnicodeDecodeError:
            raise InputError(f"{path}: the PLY header is not ASCII text") from None
        self.ascii, self.elements, self.texture = None, [], False
        for number, line in enumerate(lines, start=2):
            self._line(f"{path}: header line {number}", line.split())
        if self.ascii is None:
            raise InputError(f"{path}: the PLY header has no 'format' line")

    def _line(self, where, words):
        if not words or words[0] in ("comment", "obj_info"):
            self.texture |= len(words) > 1 and words[0] == "comment" and words[1].lower() == "texturefile"
        elif words[0] == "format":
            if len(words) != 3 or words[1] not in FORMATS:
                raise InputError(f"{where}: expected 'format' and one of {', '.join(FORMATS)} and a version")
            self.ascii = words[1] == "ascii"
        elif words[0] == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise InputError(f"{where}: expected 'element NAME COUNT', got {' '.join(words)[:60]!r}")
            self.elements.append((words[1], int(words[2]), []))
        elif words[0] == "property":
            if not self.elements:
                raise InputError(f"{where}: a property before any element")
            if len(words) == 3 and words[1] in SIZES:
                size = SIZES[words[1]]
            elif len(words) == 5 and words[1] == "list" and words[2] in SIZES and words[3] in SIZES:
                size = ("list", SIZES[words[2]], SIZES[words[3]])
            else:
                raise InputError(f"{where}: unknown property {' '.join(words)[:60]!r}")
            self.elements[-1][2].append((words[-1], size))
        else:
            raise InputError(f"{where}: unknown header keyword {words[0][:30]!r}")

    def count(self, name):
        return sum(count for element, count, _ in self.elements if element == name)

    def least_bytes(self, properties):
        """The fewest bytes one element of these properties takes in the file."""
        if self.ascii:
            return 2 * len(properties)              # "0 " each
        return sum(size[1] if isinstance(size, tuple) else size for _, size in properties)

    def check(self, vertex_room, triangle_room):
        """Refuse, naming the file, a header whose counts pass the scene's room for more vertices and
        triangles, or need more bytes than the file has. A face of n corners gives n - 2 triangles:
        at least one each."""
        names = {name: [p for p, _ in props] for name, _, props in self.elements}
        if not {"x", "y", "z"} <= set(names.get("vertex", ())):
            raise InputError(f"{self.path}: the PLY file has no 'vertex' element with x, y and z")
        if not set(FACE_LISTS) & set(names.get("face", ())) or self.count("face") == 0:
            raise InputError(f"{self.path}: the PLY file has no faces (an empty mesh, or a point cloud)")
        for what, count, room in (("vertices", self.count("vertex"), vertex_room),
                                  ("faces", self.count("face"), triangle_room)):
            if count > room:
                raise InputError(f"{self.path}: the PLY header claims {count} {what}, more than the scene has room "
                                 f"for ({room}; scenes/FORMAT.md, Limits)")
        needed = sum(count * self.least_bytes(props) for _, count, props in self.elements)
        if needed > self.data_bytes:
            claims = ", ".join(f"{count} {name}" for name, count, _ in self.elements)
            raise InputError(f"{self.path}: the PLY header claims {claims}, which need at least {needed} bytes, "
                             f"but the file has {self.data_bytes} after its header (truncated, or a false header)")

    def unmodelled(self):
        """What the file holds that the toolkit does not model, in words."""
        found = []
        for name, _, props in self.elements:
            extra = {p for p, _ in props} - ({"x", "y", "z"} if name == "vertex" else
                                             set(FACE_LISTS) if name == "face" else set())
            if name not in ("vertex", "face"):
                found.append(f"'{name}' elements")
                continue
            for meaning, known in MEANINGS.items():
                if extra & known:
                    found.append(f"{'vertex' if name == 'vertex' else 'face'} {meaning}")
            found += [f"{name} property '{p}'" for p in sorted(extra - set().union(*MEANINGS.values()))]
        if self.texture:
            found.append("a texture (TextureFile)")
        return found
