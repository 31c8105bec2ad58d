"""How one record that host and device share is described, and what is generated from it: the
numpy dtype (with C's offsets: a float4 is 16-byte aligned), the C struct, its structure-of-arrays
access and the sizeof/offsetof checks. The records themselves are described in toolkit/core/layout.py.
"""
from functools import cached_property

import numpy as np
import pyopencl as cl

from toolkit.core.c_formula import HELPER   # how every generated helper is declared (cl/common.h)

# C type -> (numpy base type, element count, alignment in bytes). OpenCL C aligns a vector
# type to its size; numpy's align=True would align a float32 x 4 sub-array to 4 bytes only.
# A float3 takes the room of a float4 in OpenCL C (size and alignment 16): numpy sees 4 floats.
_C_TYPES = {"float": ("float32", 1, 4), "int": ("int32", 1, 4), "uint": ("uint32", 1, 4),
            "float3": ("float32", 4, 16),
            "float4": ("float32", 4, 16), "int4": ("int32", 4, 16), "uint4": ("uint32", 4, 16),
            "float8": ("float32", 8, 32), "int8": ("int32", 8, 32)}


def _align(offset, alignment):
    return (offset + alignment - 1) // alignment * alignment


def frozen(records):
    """The first of `records` (a numpy structured array), read-only: a kernel argument that cannot
    change in place, so program.launch knows it by the object, without comparing its bytes at
    every launch. A record to change between launches is made with zeros(1)[0] instead."""
    records.flags.writeable = False
    return records[0]


class Record:
    """A struct of named fields of the C types in _C_TYPES, described once for host and device."""
    def __init__(self, name, fields, doc=""):
        self.name, self.fields, self.doc = name, list(fields), doc
        offsets, offset, largest = [], 0, 1
        for _, t in self.fields:
            base, count, alignment = _C_TYPES[t]
            offset = _align(offset, alignment)
            offsets.append(offset)
            offset += np.dtype(base).itemsize * count
            largest = max(largest, alignment)
        self.dtype = np.dtype({"names": [f for f, _ in self.fields],
                               "formats": [(_C_TYPES[t][0], (_C_TYPES[t][1],)) if _C_TYPES[t][1] > 1
                                           else _C_TYPES[t][0] for _, t in self.fields],
                               "offsets": offsets, "itemsize": _align(offset, largest)})
        # the fields record() sets (all but the padding), worked out once: records are made per launch
        self.settable = frozenset(f for f, _ in self.fields if not f.startswith("pad"))

    def c_struct(self):
        lines = [f"/* {self.doc} */"] if self.doc else []
        lines.append("typedef struct {")
        lines += [f"    {t} {f};" for f, t in self.fields]
        lines.append(f"}} {self.name};")
        return "\n".join(lines)

    def c_soa(self):
        """Structure-of-arrays access to records of this type, all in one global buffer of
        `capacity` records (array after array: consecutive work-items touch consecutive words):
        <Name>SoA, <name>_soa(memory, capacity) to find the arrays, and <name>_load /
        <name>_store to move one record in and out."""
        lower = _snake(self.name)
        arrays = self.soa_arrays
        lines = [f"/* {self.name} as a structure of arrays: consecutive work-items touch consecutive words. */",
                 "typedef struct {"]
        lines += [f"    __global {t}* {a};" + (f"   /* {' (.xyz), '.join(held)} (.w) */" if len(held) > 1 else "")
                  for a, t, held in arrays]
        lines.append(f"}} {self.name}SoA;")
        lines.append("/* The arrays of `capacity` records (a multiple of 4) stored one after another in `memory`. */")
        lines.append(f"{HELPER} {self.name}SoA {lower}_soa(__global void* memory, int capacity) {{")
        lines.append("    __global uchar* m = (__global uchar*)memory;")
        lines.append(f"    {self.name}SoA s;")
        for a, t, _ in arrays:
            lines.append(f"    s.{a} = (__global {t}*)m;")
            lines.append(f"    m += (size_t)capacity * sizeof({t});")
        lines.append("    return s;\n}")
        lines.append(f"{HELPER} {self.name} {lower}_load({self.name}SoA s, int i) {{")
        lines.append(f"    {self.name} r;")
        for a, t, held in arrays:
            if len(held) == 1:
                lines.append(f"    r.{a} = s.{a}[i];")
            else:   # a float3 and the float after it, in one float4
                lines += [f"    {t} {a}_word = s.{a}[i];", f"    r.{held[0]} = {a}_word.xyz;",
                          f"    r.{held[1]} = {a}_word.w;"]
        lines.append("    return r;\n}")
        lines.append(f"{HELPER} void {lower}_store({self.name}SoA s, int i, const {self.name}* r) {{")
        lines += [f"    s.{a}[i] = " + (f"r->{a};" if len(held) == 1 else f"({t})(r->{held[0]}, r->{held[1]});")
                  for a, t, held in arrays]
        lines.append("}")
        return "\n".join(lines)

    def soa_offset(self, field, capacity):
        """Byte offset of `field`'s array in a structure-of-arrays buffer of `capacity` records."""
        offset = 0
        for a, t, held in self.soa_arrays:
            if field == a:
                return offset
            if field in held:
                raise KeyError(f"{self.name}.{field} is stored in the .w of the array {a!r}")
            offset += capacity * self.dtype[a].itemsize
        raise KeyError(field)

    def soa_buffer(self, context, capacity):
        """One device buffer that holds `capacity` records as a structure of arrays (see c_soa)."""
        if capacity % 4:
            raise ValueError("a structure-of-arrays capacity must be a multiple of 4 (float4 alignment)")
        return cl.Buffer(context, cl.mem_flags.READ_WRITE, max(1, capacity) * sum(
            self.dtype[f].itemsize for f, _ in self.soa_fields))

    @cached_property
    def soa_arrays(self):
        """The arrays of the structure-of-arrays form: (array name, C type, fields it holds).
        One per field, alignment padding left out; a float3 and a float declared right after it
        share one float4 array, named after the float3 (the float in .w): each value has a name
        of its own in the record, and the stream keeps one 16-byte word for both."""
        fields = [(f, t) for f, t in self.fields if not f.startswith("pad")]
        arrays = []
        while fields:
            (f, t), rest = fields[0], fields[1:]
            if t == "float3" and rest and rest[0][1] == "float":
                arrays.append((f, "float4", [f, rest[0][0]]))
                rest = rest[1:]
            else:
                arrays.append((f, t, [f]))
            fields = rest
        return arrays

    @property
    def soa_fields(self):
        """(array name, C type) of each array of the structure-of-arrays form (soa_arrays)."""
        return [(a, t) for a, t, _ in self.soa_arrays]

    def record(self, **values):
        """One record with every field but the padding set by name (a field left out is an error),
        read-only (frozen)."""
        if values.keys() != self.settable:    # else: a padding field given, a field left out or unknown
            missing, unknown = self.settable - values.keys(), values.keys() - set(self.dtype.names)
            if missing or unknown:
                raise TypeError(f"{self.name}: missing fields {sorted(missing)}, unknown fields {sorted(unknown)}")
        out = self.zeros(1)
        out[0] = tuple(values.get(name, 0) for name in self.dtype.names)   # every field at once (padding 0)
        return frozen(out)

    def zeros(self, n):
        return np.zeros(n, self.dtype)

    def layout_checks(self):
        """(what, C expression, value numpy expects) for sizeof and every offsetof."""
        out = [(f"sizeof({self.name})", f"sizeof({self.name})", self.dtype.itemsize)]
        out += [(f"offsetof({self.name}, {f})", f"__builtin_offsetof({self.name}, {f})",
                 self.dtype.fields[f][1]) for f, _ in self.fields]
        return out


def _snake(name):
    return "".join("_" + c.lower() if c.isupper() and i else c.lower() for i, c in enumerate(name))
