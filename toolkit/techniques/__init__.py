"""The registry of techniques: name -> class. Each has a host module and a cl/ file of the same name."""
from .pt_compact_regen import PtCompactRegen
from .pt_inplace_regen import PtInplaceRegen
from .pt_naive import PtNaive

TECHNIQUES = {cls.name: cls for cls in (PtNaive, PtInplaceRegen, PtCompactRegen)}


def get_technique(name):
    try:
        return TECHNIQUES[name]
    except KeyError:
        raise ValueError(f"unknown technique {name!r}; known: {', '.join(TECHNIQUES)}") from None
