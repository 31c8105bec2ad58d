"""Named quantities packed into the unused .w component of a record's float4 field.

A float4 position or throughput has a spare fourth float; the kernels keep a scalar there rather
than grow the record (and the memory traffic of every step). A `PackedW` gives that scalar its name
once (toolkit/core/layout.py lists them): C reads and writes it as RECORD_NAME(pointer), an
lvalue macro generated into layout.h, and numpy as record[name] with packed_w_dtype(). (Not
called lanes: in this toolkit a lane is a work-item of a warp, toolkit/core/simd.py.)
"""
import re

import numpy as np


class PackedW:
    def __init__(self, record, field, name, doc):
        if record.dtype.fields[field][0].shape != (4,):
            raise ValueError(f"{record.name}.{field} is not a float4: no .w component")
        self.record, self.field, self.name, self.doc = record, field, name, doc
        self.offset = record.dtype.fields[field][1] + 12   # .w: the fourth float
        self.macro = re.sub(r"(?<!^)(?=[A-Z])", "_", record.name).upper() + "_" + name.upper()

    def c_macro(self):
        return (f"/* {self.record.name}.{self.field}.w: {self.doc} */\n"
                f"#define {self.macro}(r) ((r)->{self.field}.w)")


def packed_w_dtype(record, packed):
    """`record`'s numpy dtype with its packed quantities as extra float32 fields (over the .w components)."""
    fields = {name: record.dtype.fields[name][:2] for name in record.dtype.names}
    fields.update({w.name: (np.dtype("float32"), w.offset) for w in packed})
    return np.dtype({"names": list(fields), "formats": [f for f, _ in fields.values()],
                     "offsets": [o for _, o in fields.values()], "itemsize": record.dtype.itemsize})
