"""Record layouts described once: each description gives the numpy dtype and the C struct.

The device structs are generated from these descriptions into the source every program is
built from (see `c_header()`), so host and device can never disagree on a layout.
"""
import numpy as np

_C_TYPES = {"float": ("float32", 1), "int": ("int32", 1), "uint": ("uint32", 1),
            "float4": ("float32", 4), "int4": ("int32", 4), "uint4": ("uint32", 4)}


class Record:
    def __init__(self, name, fields, doc=""):
        self.name, self.fields, self.doc = name, list(fields), doc
        self.dtype = np.dtype([(f, _C_TYPES[t][0], (_C_TYPES[t][1],)) if _C_TYPES[t][1] > 1
                               else (f, _C_TYPES[t][0]) for f, t in self.fields], align=True)

    def c_struct(self):
        lines = [f"/* {self.doc} */"] if self.doc else []
        lines.append(f"typedef struct {{")
        lines += [f"    {t} {f};" for f, t in self.fields]
        lines.append(f"}} {self.name};")
        return "\n".join(lines)

    def c_soa(self):
        """Structure-of-arrays access to records of this type, one global buffer per field:
        <Name>SoA, <NAME>_SOA_PARAMS(p) for kernel parameters p_<field>, <NAME>_SOA(p) to
        bundle them, and <name>_load / <name>_store to move one record in and out."""
        upper, lower = _snake(self.name).upper(), _snake(self.name)
        fields = self.soa_fields
        lines = [f"/* {self.name} as a structure of arrays: consecutive work-items touch consecutive words. */",
                 "typedef struct {"]
        lines += [f"    __global {t}* {f};" for f, t in fields]
        lines.append(f"}} {self.name}SoA;")
        params = ", ".join(f"__global {t}* p##_{f}" for f, t in fields)
        lines.append(f"#define {upper}_SOA_PARAMS(p) {params}")
        bundle = ", ".join(f"p##_{f}" for f, _ in fields)
        lines.append(f"#define {upper}_SOA(p) (({self.name}SoA){{{bundle}}})")
        lines.append(f"inline {self.name} {lower}_load({self.name}SoA s, int i) {{")
        lines.append(f"    {self.name} r;")
        lines += [f"    r.{f} = s.{f}[i];" for f, _ in fields]
        lines.append("    return r;\n}")
        lines.append(f"inline void {lower}_store({self.name}SoA s, int i, const {self.name}* r) {{")
        lines += [f"    s.{f}[i] = r->{f};" for f, _ in fields]
        lines.append("}")
        return "\n".join(lines)

    def soa_buffers(self, context, n):
        """One device buffer per field, in field order (matching <NAME>_SOA_PARAMS)."""
        import pyopencl as cl
        return [cl.Buffer(context, cl.mem_flags.READ_WRITE, max(1, n) * self.dtype[f].itemsize)
                for f, _ in self.soa_fields]

    @property
    def soa_fields(self):
        """Fields stored in structure-of-arrays form (alignment padding is left out)."""
        return [(f, t) for f, t in self.fields if not f.startswith("pad")]

    def zeros(self, n):
        return np.zeros(n, self.dtype)


# float4-first layouts keep every record 16-byte aligned on host and device alike.
BVH_NODE = Record("BvhNode", [
    ("lo", "float4"),   # box minimum; .w unused
    ("hi", "float4"),   # box maximum; .w unused
    ("first", "int"),   # leaf: first triangle; inner: index of the right child (left = this + 1)
    ("count", "int"),   # leaf: number of triangles (> 0); inner: 0
    ("axis", "int"),    # inner: split axis, to visit the nearer child first
    ("pad", "int"),
], "A flattened BVH node (depth-first order), 48 bytes.")

TRIANGLE = Record("Triangle", [
    ("v0", "float4"),   # .w unused
    ("v1", "float4"),   # the vertices themselves, not edges: a shared vertex is bit-identical
    ("v2", "float4"),   #   in every triangle, which the watertight ray test needs
    ("material", "int"),
    ("prim", "int"),    # index of the triangle in the scene (BVH order differs)
    ("light_pdf", "float"),  # density per unit area with which light sampling picks a point here
    ("light", "int"),        # index into the light array, -1: not a light
], "A triangle in BVH leaf order, 64 bytes.")

MATERIAL = Record("Material", [
    ("reflectance", "float4"),
    ("type", "int"),
    ("ior", "float"),
    ("alpha", "float"),
    ("pad", "int"),
], "A material of scenes/FORMAT.md; `type` is one of the MAT_* defines.")

LIGHT = Record("LightTri", [
    ("emission", "float4"),
    ("cdf", "float"),        # inclusive cumulative selection probability
    ("triangle", "int"),     # index into the triangle array (BVH order)
    ("pad0", "int"),
    ("pad1", "int"),
], "An emitting triangle, chosen for next-event estimation in proportion to its power.")

CAMERA = Record("Camera", [
    ("origin", "float4"),
    ("forward", "float4"),   # unit viewing direction f
    ("right", "float4"),     # r * tx (FORMAT.md)
    ("up", "float4"),        # u * ty
    ("width", "int"),
    ("height", "int"),
    ("pad0", "int"),
    ("pad1", "int"),
], "The pinhole camera of scenes/FORMAT.md, for the rendered resolution.")

PATH_STATE = Record("PathState", [
    ("origin", "float4"),      # next ray origin (already offset off the surface)
    ("dir", "float4"),         # next ray direction (unit)
    ("throughput", "float4"),  # product of BSDF weights so far
    ("radiance", "float4"),    # radiance gathered so far
    ("prev_pdf", "float"),     # solid-angle pdf of the BSDF sample that chose dir (for MIS)
    ("prev_specular", "int"),  # 1: dir came from the camera or a delta lobe
    ("bounce", "int"),         # surface vertices so far
    ("pixel", "int"),
    ("sample", "int"),         # sample index within the pixel: keys the random numbers
    ("slot", "int"),           # where the finished sample's radiance goes in this pass's output
    ("pad1", "int"),
    ("pad2", "int"),
], "The state of one camera path between two extension steps, 96 bytes.")

SHADOW_RAY = Record("ShadowRay", [
    ("origin", "float4"),        # .w = length of the segment to test
    ("dir", "float4"),
    ("contribution", "float4"),  # radiance added to the sample if the segment is unoccluded
    ("slot", "int"),             # the sample's slot in the pass's output
    ("pad0", "int"),
    ("pad1", "int"),
    ("pad2", "int"),
], "A next-event-estimation shadow ray waiting to be traced, 64 bytes.")

BDPT_VERTEX = Record("BdptVertex", [
    ("pos", "float4"),       # position; .w = pdf_fwd: area density with which its own subpath generated it
    ("normal", "float4"),    # geometric normal; .w = prev_pdf_rev: area density of generating the
                             #   previous vertex of the subpath from this one (reverse direction)
    ("wo", "float4"),        # unit direction to the previous vertex of the subpath
    ("beta", "float4"),      # subpath throughput up to this vertex (light paths: includes Le / pdf)
    ("material", "int"),
    ("flags", "int"),        # VERTEX_DELTA | VERTEX_CAMERA | VERTEX_LIGHT (cl/bdpt.h)
    ("light", "int"),        # index into the light array if the vertex lies on a light, else -1
    ("pad", "int"),
], "A stored BDPT path vertex, 80 bytes (the talk's vertex is 128: ours packs pdfs into .w).")

SUBPATH = Record("Subpath", [
    ("origin", "float4"),     # next ray origin; .w = solid-angle pdf of dir (0 after a delta bounce)
    ("dir", "float4"),        # next ray direction
    ("beta", "float4"),       # throughput; .w = roulette normaliser (1 for eye paths)
    ("prev_pos", "float4"),   # the last stored vertex (exact, not offset)
    ("prev_normal", "float4"),
    ("slot", "int"),          # the sample's slot in the sample pool
    ("vertices", "int"),      # vertices stored so far
    ("prev_flags", "int"),    # flags of the last stored vertex
    ("pad", "int"),
], "One eye or light subpath in a random-walk stream, 96 bytes.")

RECORDS = [BVH_NODE, TRIANGLE, MATERIAL, LIGHT, CAMERA, PATH_STATE, SHADOW_RAY, BDPT_VERTEX, SUBPATH]


SOA_RECORDS = [PATH_STATE, SHADOW_RAY, SUBPATH]


def _snake(name):
    return "".join("_" + c.lower() if c.isupper() and i else c.lower() for i, c in enumerate(name))


def c_header(records=RECORDS):
    return ("/* Generated from toolkit/layout.py: do not edit by hand. */\n"
            + "\n\n".join(r.c_struct() for r in records) + "\n\n"
            + "\n\n".join(r.c_soa() for r in SOA_RECORDS) + "\n")
