"""The registry of techniques: name -> class. Each has a host module and a cl/ file of the same name."""
from toolkit.techniques.bdpt_naive_connect import BdptNaiveConnect
from toolkit.techniques.bdpt_parallel_connect import BdptParallelConnect
from toolkit.techniques.mlt import Mlt
from toolkit.techniques.pt_compact_regen import PtCompactRegen
from toolkit.techniques.pt_inplace_regen import PtInplaceRegen
from toolkit.techniques.pt_naive import PtNaive

__all__ = ["TECHNIQUES", "VARIANTS", "get_technique", "family", "PtNaive", "PtInplaceRegen", "PtCompactRegen",
           "BdptNaiveConnect", "BdptParallelConnect", "Mlt"]

TECHNIQUES = {cls.name: cls for cls in (PtNaive, PtInplaceRegen, PtCompactRegen,
                                        BdptNaiveConnect, BdptParallelConnect, Mlt)}


# Variants: the same technique with an option set, for side-by-side measurements.
VARIANTS = {"pt_compact_regen/multipass": ("pt_compact_regen", {"compaction": "multipass"}),
            "bdpt_parallel_connect/direct_scatter": ("bdpt_parallel_connect", {"coalesced_scatter": False}),
            # postponed regeneration's threshold (the talk's 60% is the default): assignment 5's write-up
            "bdpt_parallel_connect/regen30": ("bdpt_parallel_connect", {"regenerate_fraction": 0.3}),
            "bdpt_parallel_connect/regen100": ("bdpt_parallel_connect", {"regenerate_fraction": 1.0}),
            # mlt's starts (its default is pool): the talk's naive start, and the weighted resample
            "mlt/naive": ("mlt", {"start": "naive"}), "mlt/pool": ("mlt", {"start": "pool"}),
            "mlt/resample": ("mlt", {"start": "resample"})}


def get_technique(name):
    """(class, options) for a technique name or a variant name."""
    base, options = VARIANTS.get(name, (name, {}))
    try:
        return TECHNIQUES[base], dict(options)
    except KeyError:
        known = ", ".join([*TECHNIQUES, *VARIANTS])
        raise ValueError(f"unknown technique {name!r}; known: {known}") from None


def family(name):
    """"pt", "bdpt" or "mlt": the family of a technique or variant name (Technique.family)."""
    return get_technique(name)[0].family
