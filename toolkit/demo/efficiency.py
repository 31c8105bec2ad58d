"""SIMD efficiency per phase for each technique, beside the figure the talk gives for it.

The talk's figures (shared/seed/van_antwerpen_2011_talk.txt) are active threads per GPU warp:
~33% in the random walk of plain path tracing, ~30% in in-place regeneration's regeneration
step, ~17% in BDPT's connections done per sample, and ~99% for the techniques that keep their
work in continuous streams (stream compaction + regeneration, parallel connections, and MLT on
top of them). Ours are counted the same way (toolkit/core/simd.py), for warps of the device's W.
"""
import html

# technique -> {phase: the talk's active threads per warp}
TALK_FIGURES = {
    "pt_naive": {"extend": 0.33},
    "pt_inplace_regen": {"generate": 0.30},
    "bdpt_naive_connect": {"connect": 0.17},
    "pt_compact_regen": {"overall": 0.99},
    "bdpt_parallel_connect": {"overall": 0.99},
    "mlt": {"overall": 0.99},
}

PHASE_ORDER = ["generate", "extend", "walk", "shadow", "compact", "connect", "mutate", "accept", "overall"]


def talk_figure(technique, phase):
    """The talk's figure for this technique's phase, or None (variants share their technique's)."""
    return TALK_FIGURES.get(technique.split("/")[0], {}).get(phase)


def efficiency_rows(efficiencies):
    """{technique: {phase: efficiency}} -> (phases in a fixed order, rows of (technique, [(ours,
    talk's or None) per phase]))."""
    present = {p for eff in efficiencies.values() for p in eff}
    phases = [p for p in PHASE_ORDER if p in present] + sorted(present - set(PHASE_ORDER))
    rows = [(name, [(eff.get(p), talk_figure(name, p)) for p in phases]) for name, eff in efficiencies.items()]
    return phases, rows


def efficiency_html(efficiencies, warp_width=None):
    """The table as HTML: one row per technique, one column per phase, each cell our figure and,
    where the talk gives one, the talk's in grey beneath it."""
    phases, rows = efficiency_rows(efficiencies)
    if not rows:
        return "<p>SIMD efficiency: waiting for the first pass.</p>"

    def cell(ours, talk):
        text = "–" if ours is None else f"{ours:.1%}"
        if talk is not None:
            text += f"<br><span style='color:#777;font-size:85%'>talk ~{talk:.0%}</span>"
        return f"<td style='text-align:right;padding:2px 10px'>{text}</td>"

    head = "".join(f"<th style='padding:2px 10px'>{html.escape(p)}</th>" for p in phases)
    body = "".join(f"<tr><td style='padding:2px 10px'><b>{html.escape(name)}</b></td>"
                   + "".join(cell(*c) for c in cells) + "</tr>" for name, cells in rows)
    width = f", warps of {int(warp_width)}" if warp_width else ""
    return (f"<table class='simd-efficiency' style='border-collapse:collapse'>"
            f"<caption style='text-align:left'>SIMD efficiency: active lanes / lanes issued{width} "
            f"(an upper bound, as in the talk)</caption>"
            f"<tr><th></th>{head}</tr>{body}</table>")
