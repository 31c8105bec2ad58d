"""One figure of compare's per-phase figures (toolkit/measure/phases.py), a row per family
(path tracers, bidirectional): where the time goes, how busy the lanes were, and how far the
talk's model predicts the measured time ratios. Every number in it comes from one compare run."""
import numpy as np

from toolkit.core.images import write_atomically
from toolkit.measure.phases import HOST, model_rows

FAMILIES = {"pt": "path tracing", "bdpt": "bidirectional path tracing"}


def one_run(table):
    """(device, lanes setting, vector widths, W of the counters) that the rows share; an error if
    device, setting or W differ, since a plot must not mix runs."""
    seen = {(row["device"], row["lanes"], row["warp_width"]) for row in table.values()}
    if len(seen) != 1:
        raise ValueError(f"the rows of one phase plot must come from one device and lanes setting, got {sorted(map(str, seen))}")
    device, lanes, warp_width = seen.pop()
    widths = sorted({row["vector_width"] for row in table.values() if row["vector_width"] is not None})
    return device, lanes, widths, warp_width


def lanes_words(lanes, widths):
    """"lanes off, vector width 1" for the title: the setting and the widths the compiler reported."""
    if lanes is None:
        return "lanes: none reported by this compiler"
    if not widths:
        return f"lanes {lanes}"
    return f"lanes {lanes}, vector width {'/'.join(map(str, widths))} (the compiler's log)"


def save_phase_plot(path, table, title):
    """Write the figure to `path` (atomically: never seen half-written); returns the path."""
    from matplotlib.figure import Figure   # ~0.5 s to import: only when a plot is asked for
    device, lanes, widths, warp_width = one_run(table)
    families = [f for f in FAMILIES if any(row["family"] == f for row in table.values())]
    model = model_rows(table)
    fig = Figure(figsize=(16, 4.6 * len(families)))
    axes = fig.subplots(len(families), 3, squeeze=False)
    for k, family in enumerate(families):
        names = [n for n, row in table.items() if row["family"] == family]
        _time_bars(axes[k, 0], names, table, FAMILIES[family])
        _efficiency_bars(axes[k, 1], names, table, warp_width)
        _model_bars(axes[k, 2], names, model)
    fig.suptitle(f"{title}\n{device}; {lanes_words(lanes, widths)}; counters: warps of {warp_width}; every number from one run",
                 fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    return write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=90, format="png"))


def _time_bars(ax, names, table, family_name):
    """Stacked bars: each technique's wall time split into its stages, the host's rest hatched."""
    stages = []
    for n in names:
        for r in table[n]["phases"]:
            if r["stage"] not in stages and r["kernel"] != HOST:
                stages.append(r["stage"])
    colours = dict(zip(stages, _palette(len(stages))))
    x = np.arange(len(names))
    bottom = np.zeros(len(names))
    for stage in [*stages, HOST]:
        ms = np.array([_stage_ms(table[n]["phases"], stage) for n in names])
        ax.bar(x, ms, bottom=bottom, label=stage, color=colours.get(stage, "0.85"),
               hatch="//" if stage == HOST else None, edgecolor="0.4", lw=0.5)
        bottom += ms
    ax.set_xticks(x, names, fontsize=8)
    ax.set(ylabel="wall time of the render (ms)", title=f"{family_name}: time per phase")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, axis="y")


def _stage_ms(rows, stage):
    """The ms of one stage of a technique (several kernels may share a stage); HOST: the host's rest."""
    if stage == HOST:
        return sum(r["ms"] for r in rows if r["kernel"] == HOST)
    return sum(r["ms"] for r in rows if r["kernel"] != HOST and r["stage"] == stage)


def _efficiency_bars(ax, names, table, warp_width):
    """Path-level lane efficiency (all counted phases) beside the BVH loop's, per technique."""
    x = np.arange(len(names))
    path = [100 * table[n]["simd_efficiency"].get("overall", np.nan) for n in names]
    trav = [100 * table[n]["traversal_efficiency"].get("closest", np.nan) for n in names]
    ax.bar(x - 0.2, path, 0.4, label="paths: active / issued lanes")
    ax.bar(x + 0.2, trav, 0.4, label="BVH traversal: steps / warp's longest")
    ax.set_xticks(x, names, fontsize=8)
    ax.set(ylabel=f"lane efficiency (%), warps of {warp_width}", ylim=(0, 105), title="how busy the lanes were")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, axis="y")


def _model_bars(ax, names, model):
    """The talk's predicted time ratios beside the measured ones (reference = 1)."""
    x = np.arange(len(names))
    bars = [("predicted", "model: issued lane-steps"), ("predicted_traversal", "model: issued BVH steps (counted ones)"),
            ("measured_kernels", "measured: kernel time"), ("measured_wall", "measured: wall time")]
    for i, (key, label) in enumerate(bars):
        ax.bar(x + (i - 1.5) * 0.2, [model[n][key] for n in names], 0.2, label=label)
    ax.axhline(1.0, color="0.3", lw=0.8)
    ax.set_xticks(x, names, fontsize=8)
    ax.set(ylabel=f"time / {model[names[0]]['reference']}'s (lower is faster)",
           title="model: time ~ work / (W x efficiency), vs measured")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, axis="y")


def _palette(n):
    from matplotlib import colormaps
    cmap = colormaps["tab10"]
    return [cmap(i % 10) for i in range(n)]
