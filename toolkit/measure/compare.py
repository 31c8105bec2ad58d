"""`python -m toolkit compare`: several techniques on one scene with the same sample budget.

Prints a table (seconds, samples/s, SIMD efficiency per phase, RMSE against the reference and
against each other) and saves plots: efficiency and stream occupancy per iteration, and an
image strip with false-colour error images.
"""

import numpy as np

from toolkit.api import as_scene, render
from toolkit.core.images import to_srgb8, write_image
from toolkit.core.render_options import with_fields
from toolkit.core.validate import writable_folder
from toolkit.measure.phase_plot import FAMILIES as PHASE_FAMILIES, save_phase_plot
from toolkit.measure.phases import format_phases, name_width, phase_rows
from toolkit.techniques import get_technique
from toolkit.measure.reference import reference_at, rmse

PHASES = ["generate", "extend", "walk", "shadow", "compact", "connect"]


def compare(scene, techniques, spp=None, options=None, out_dir="out/compare", plots=True, phase_plot=None,
            **fields):
    """Render `scene` with each technique; returns {technique: figures} and writes images/plots.
    `options`: a RenderOptions for every render (toolkit/core/render_options.py: warp_width None is
    the device's, and each row says which), with `spp` and any other of its fields as keywords on
    top, as toolkit.render takes them. Each row also has its time per phase (kernel) beside its lane
    efficiency ("phases", toolkit/measure/phases.py), all from this one run (time_phases);
    `phase_plot`: where the figure of them goes (default <out_dir>/<scene>_phases.png, with the other plots;
    none when no technique has a panel in it: mlt alone)."""
    options = with_fields(options, **fields, **({} if spp is None else {"spp": spp}))
    out_dir = writable_folder(out_dir)      # before the renders: a bad folder must not cost their time
    scene = as_scene(scene)
    width, height = options.resolution or (scene.camera.width, scene.camera.height)
    options = with_fields(options, resolution=(width, height), time_phases=True)
    ref, _ = reference_at(scene, width, height)
    results, table = {}, {}
    for name in techniques:
        result = render(scene, name, options)
        path = out_dir / f"{scene.name}_{name.replace('/', '_')}.exr"
        write_image(path, result.image.astype(np.float32))
        results[name] = result
        table[name] = {
            "seconds": result.stats["seconds"],
            "samples_per_second": result.stats["samples_per_second"],
            "simd_efficiency": result.stats["simd_efficiency"],
            "traversal_efficiency": result.stats["traversal_efficiency"],
            "traversal_steps": result.stats["traversal_steps_per_sample"].get("closest", float("nan")),
            "bvh": options.bvh,
            "warp_width": result.stats["warp_width"],
            "warp_width_source": result.stats["warp_width_source"],
            **{k: result.stats[k] for k in ("stream_size", "pool_size", "work_sizes_source") if k in result.stats},
            **{k: result.stats[k] for k in ("lanes", "vector_width", "vector_widths", "lanes_summary")},
            "rmse": rmse(result.image, ref) if ref is not None else None,
            "nonfinite": result.stats["nonfinite"],
            "out": str(path),
            "family": get_technique(name)[0].family, "device": result.stats["device"],
            **{k: result.stats[k] for k in ("kernel_times", "kernel_span_seconds", "simd_lane_steps",
                                            "traversal_lane_steps")},
            "phases": phase_rows(result.stats),
        }
    for a in techniques:
        table[a]["rmse_vs"] = {b: rmse(results[a].image, results[b].image) for b in techniques if b != a}
    if plots:
        plot_paths = save_plots(scene.name, results, ref, out_dir, next(iter(table.values()))["warp_width"])
        title = f"{scene.name} {width}x{height}, {options.spp} spp: time per phase and lane efficiency"
        if any(row["family"] in PHASE_FAMILIES for row in table.values()):   # mlt alone has no panel in it
            plot_paths["phases"] = str(save_phase_plot(phase_plot or out_dir / f"{scene.name}_phases.png", table,
                                                       title))
        for name in techniques:
            table[name]["plots"] = plot_paths
    return table


def format_table(table, warp_width=None):
    """The table as text; `warp_width` None: the W that the rows were counted with (and why)."""
    first = next(iter(table.values()))
    why = None
    if warp_width is None:
        warp_width, why = first.get("warp_width", 32), first.get("warp_width_source")
    phases = [p for p in PHASES if any(p in row["simd_efficiency"] for row in table.values())]
    w = name_width(table, 28)
    head = f"{'technique':<{w}}{'seconds':>9}{'samples/s':>12}" + "".join(f"{p:>10}" for p in phases) + \
        f"{'overall':>10}{'BVH trav':>10}{'steps':>8}{'RMSE ref':>11}"
    lines = [f"SIMD efficiency = active lanes / lanes issued, warps of {warp_width} (an upper bound, as in the talk);",
             "BVH trav = traversal steps per lane / the warp's longest traversal (divergence inside intersection);",
             f"steps = BVH nodes visited by closest-hit rays per sample ({first['bvh']} BVH, --bvh)",
             *([f"W = {warp_width}: {why} (--warp-width overrides)"] if why and why != "given" else []),
             *in_flight_lines(table),
             *lanes_lines(table),
             head, "-" * len(head)]
    for name, row in table.items():
        eff = row["simd_efficiency"]
        cells = "".join(f"{eff[p]:>10.1%}" if p in eff else f"{'-':>10}" for p in phases)
        r = f"{row['rmse']:>11.5f}" if row["rmse"] is not None else f"{'-':>11}"
        trav = row["traversal_efficiency"].get("closest", float("nan"))
        lines.append(f"{name:<{w}}{row['seconds']:>9.2f}{row['samples_per_second']:>12,.0f}{cells}"
                     f"{eff.get('overall', float('nan')):>10.1%}{trav:>10.1%}{row['traversal_steps']:>8.1f}{r}")
    names = list(table)
    if all("phases" in row for row in table.values()):   # rows read back from an older JSON have none
        lines += ["", format_phases(table), ""]
    if len(names) > 1:
        lines.append("RMSE between techniques: " + ", ".join(
            f"{a} vs {b} {table[a]['rmse_vs'][b]:.5f}" for i, a in enumerate(names) for b in names[i + 1:]))
    return "\n".join(lines)


def in_flight_lines(table):
    """One line per stream or pool size the rows ran with, and why (toolkit/opencl/work_sizes.py)."""
    seen = {}
    for name, row in table.items():
        for option in ("stream_size", "pool_size"):
            if option in row:
                seen.setdefault((option, row[option], row.get("work_sizes_source")), []).append(name)
    return [f"{option} = {size:,}: {why} ({', '.join(names)})" for (option, size, why), names in seen.items()]


def lanes_lines(table):
    """Whether the rows ran work-items as SIMD lanes, and how wide (toolkit/opencl/lanes.py)."""
    seen = {}
    for name, row in table.items():
        if "lanes_summary" in row:
            seen.setdefault(row["lanes_summary"], []).append(name)
    return [f"{summary} ({', '.join(names)})" for summary, names in seen.items()]


DRAIN_NOTE = ("Shaded, from the dashed line on: the final drain of a pass. Every sample of the budget has started, "
              "nothing regenerates, and the stream empties.\nIts last steps trace a few long paths: one path in a "
              "warp of 32 is 3% efficiency, but such a step issues a single warp, so the drain weighs little in the "
              "totals of the table.")


def drain_spans(steps):
    """(first, last) iteration of each run of steps marked `draining` (one per pass)."""
    spans = []
    for it in steps:
        if not it.get("draining"):
            continue
        if spans and it["iteration"] <= spans[-1][1] + 1:
            spans[-1][1] = it["iteration"]
        else:
            spans.append([it["iteration"], it["iteration"]])
    return [tuple(span) for span in spans]


def save_plots(scene_name, results, ref, out_dir, warp_width):
    # Figures drawn straight onto an Agg canvas: no pyplot state, and the caller's backend
    # (e.g. inline plots in a notebook) is left alone. Imported here: matplotlib takes ~0.5 s to
    # import, and only a compare that writes plots needs it.
    from matplotlib.figure import Figure
    paths = {}

    fig = Figure(figsize=(12, 4.8))
    ax1, ax2 = fig.subplots(1, 2)
    drained = False
    for name, result in results.items():
        steps = [it for it in result.iterations if it["phase"] in ("extend", "walk")]
        if not steps:
            continue
        x = [it["iteration"] for it in steps]
        line, = ax1.plot(x, [100 * it["efficiency"] for it in steps], label=name, lw=1)
        ax2.plot(x, [100 * it["active"] / it["capacity"] for it in steps], label=name, lw=1)
        for first, last in drain_spans(steps):
            for ax in (ax1, ax2):
                ax.axvspan(first - 0.5, last + 0.5, color=line.get_color(), alpha=0.12, lw=0,
                           label=None if drained else "final drain (budget spent)")
                ax.axvline(first - 0.5, color=line.get_color(), ls="--", lw=0.8)
            drained = True
    ax1.set(xlabel="extension iteration", ylabel=f"SIMD efficiency of extend/walk (%), W={warp_width}",
            title=f"{scene_name}: active lanes per issued lane", ylim=(0, 105))
    ax2.set(xlabel="extension iteration", ylabel="stream occupancy (% of lanes with a live path)",
            title=f"{scene_name}: live paths in the stream", ylim=(0, 105))
    for ax in (ax1, ax2):
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    if drained:
        fig.text(0.01, 0.01, DRAIN_NOTE, fontsize=8, va="bottom")
        fig.tight_layout(rect=(0, 0.1, 1, 1))
    else:
        fig.tight_layout()
    paths["efficiency"] = str(out_dir / f"{scene_name}_efficiency_per_iteration.png")
    fig.savefig(paths["efficiency"], dpi=100)

    expected = ref if ref is not None else next(iter(results.values())).image
    errors = {n: np.abs(r.image - expected).mean(-1) for n, r in results.items()}
    vmax = max(float(np.percentile(e, 99)) for e in errors.values()) or 1.0
    n = len(results)
    fig = Figure(figsize=(3.2 * n, 6.4))
    axes = fig.subplots(2, n, squeeze=False)
    for k, (name, result) in enumerate(results.items()):
        axes[0, k].imshow(to_srgb8(result.image.astype(np.float32)))
        axes[0, k].set_title(name, fontsize=9)
        im = axes[1, k].imshow(errors[name], cmap="inferno", vmin=0, vmax=vmax)
        axes[1, k].set_title(f"|error| vs {'reference' if ref is not None else 'first'}", fontsize=9)
        for ax in axes[:, k]:
            ax.set_xticks([])
            ax.set_yticks([])
    fig.colorbar(im, ax=axes[1, :].tolist(), label="absolute error (linear radiance, mean of RGB)", shrink=0.8)
    paths["images"] = str(out_dir / f"{scene_name}_image_strip.png")
    fig.savefig(paths["images"], dpi=100)
    return paths
