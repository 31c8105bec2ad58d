"""The study's plots: RMSE against time (log-log, with the 1/sqrt(t) guide), bias^2 and
variance stacked per run at the largest budget, an image strip with false-colour error at
equal time, and, with more than one budget, the image grid: every run at every budget beside
the reference (the talk's figure of MLT at 10 s, 1 min and 10 min). Each file is written to a
temporary file and renamed over the old one."""
import numpy as np

from toolkit.core.images import to_srgb8, write_atomically
from toolkit.measure.reference import reference_at
from toolkit.measure.study.report import slope_text


def save_plots(report, renders, scene, out_dir):
    """The plots of `report` in `out_dir`: {"rmse_vs_time", "bias_variance", "image_strip", "image_grid"}:
    paths (bias_variance only where every run has a bias^2, image_grid only with several budgets).
    `renders` as in report.run_report."""
    # Imported here: matplotlib takes ~0.5 s to import, and only a study written to disk plots.
    from matplotlib.figure import Figure
    out_dir.mkdir(parents=True, exist_ok=True)
    name = report["scene"]
    paths = {"rmse_vs_time": _save(_rmse_vs_time(Figure(figsize=(7.5, 5)), report),
                                   out_dir / f"{name}_study_rmse_vs_time.png")}
    last = [run["points"][-1] for run in report["runs"].values()]
    if all(p["bias2"] is not None for p in last):
        fig = Figure(figsize=(max(5.0, 1.1 * len(last) + 2), 4.8))
        paths["bias_variance"] = _save(_bias_variance(fig, report), out_dir / f"{name}_study_bias_variance.png")
    fig = Figure(figsize=(2.6 * len(report["runs"]) + 1, 5.6))
    paths["image_strip"] = _save(_image_strip(fig, report, renders, scene), out_dir / f"{name}_study_image_strip.png")
    if len(report["budgets"]) > 1:
        fig = Figure(figsize=(2.1 * (len(report["budgets"]) + 1), 2.4 * len(report["runs"]) + 0.4))
        paths["image_grid"] = _save(_image_grid(fig, report, renders, scene), out_dir / f"{name}_study_image_grid.png")
    return paths


def _save(fig, path):
    write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=100, format="png"))
    return str(path)


def _rmse_vs_time(fig, report):
    runs = report["runs"]
    ax = fig.subplots()
    guide = None
    for label, run in runs.items():
        pts = [p for p in run["points"] if p["relative_rmse"]]
        if not pts:
            continue
        t = [p["time"] for p in pts]
        y = [100 * p["relative_rmse"] for p in pts]
        e = [100 * (p["relative_rmse_se"] or 0) for p in pts]
        ax.errorbar(t, y, yerr=e, marker="o", ms=3, capsize=2, lw=1,
                    label=f"{label} (slope {slope_text(run['slope'])})")
        if guide is None:
            guide = (t[0], y[0])
    if guide is not None:
        lo = min(p["time"] for r in runs.values() for p in r["points"])
        hi = max(p["time"] for r in runs.values() for p in r["points"])
        ts = np.geomspace(lo, hi, 20)
        ax.plot(ts, guide[1] * np.sqrt(guide[0] / ts), "k--", lw=0.8, label="1/sqrt(t) guide")
    ax.axhline(100 * report["target"], color="grey", lw=0.8, ls=":", label=f"target {report['target']:.0%}")
    ax.set(xscale="log", yscale="log", xlabel="wall time of one repetition (s, render only)",
           ylabel="relative RMSE against the reference (% of its mean)",
           title=f"{report['scene']}: error against time, {report['repeats']} repetitions per point")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def _bias_variance(fig, report):
    labels = list(report["runs"])
    last = [report["runs"][l]["points"][-1] for l in labels]
    ax = fig.subplots()
    x = np.arange(len(labels))
    scale = [p["reference_mean"] ** 2 / 1e4 for p in last]       # in (% of the mean)^2
    b = [max(p["bias2"], 0.0) / s for p, s in zip(last, scale)]
    v = [p["variance"] / s for p, s in zip(last, scale)]
    ax.bar(x, b, yerr=[p["bias2_se"] / s for p, s in zip(last, scale)], capsize=3, label="bias²", color="C3")
    ax.bar(x, v, bottom=b, yerr=[p["variance_se"] / s for p, s in zip(last, scale)], capsize=3,
           label="variance", color="C0")
    ax.set_xticks(x)
    ax.set_xticklabels(labels, rotation=30, ha="right", fontsize=8)
    budget = report["budgets"][-1]
    ax.set(ylabel="relative MSE of one repetition ((% of the mean)²)",
           title=f"{report['scene']}: bias² and variance at the largest budget "
                 f"({budget:g} {'s' if report['budget_unit'] == 'seconds' else 'spp'})")
    ax.legend()
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    return fig


def _image_strip(fig, report, renders, scene):
    runs = report["runs"]
    labels = list(runs)
    k = len(report["budgets"]) - 1
    shown = {l: renders[(l, k)]["images"][0] for l in labels}
    refs = {l: reference_at(scene, *runs[l]["resolution"])[0] for l in labels}
    errors = {l: np.abs(shown[l] - refs[l]).mean(-1) for l in labels}
    vmax = max(float(np.percentile(e, 99)) for e in errors.values()) or 1.0
    axes = fig.subplots(2, len(labels), squeeze=False)
    for i, l in enumerate(labels):
        axes[0, i].imshow(to_srgb8(shown[l].astype(np.float32)))
        axes[0, i].set_title(f"{l}\n{runs[l]['points'][k]['spp']} spp", fontsize=8)
        im = axes[1, i].imshow(errors[l], cmap="inferno", vmin=0, vmax=vmax)
        axes[1, i].set_title("|error| vs reference", fontsize=8)
        for a in axes[:, i]:
            a.set_xticks([])
            a.set_yticks([])
    fig.colorbar(im, ax=axes[1, :].tolist(), label="|error| (radiance, mean of RGB)", shrink=0.8)
    fig.suptitle(f"{report['scene']}: equal time, the largest budget, first repetition", fontsize=9)
    return fig


def _image_grid(fig, report, renders, scene):
    """A row per run, a column per budget (the first repetition), the reference at the end of
    the first row; one exposure for all, from the reference (its 98th percentile shows white, so
    that a few bright pixels, a light or a crack, do not leave the rest dark)."""
    runs, budgets = report["runs"], report["budgets"]
    unit = "s" if report["budget_unit"] == "seconds" else "spp"
    first = next(iter(runs.values()))
    ref, ref_err = reference_at(scene, *first["resolution"])
    noise = float((ref_err ** 2).mean())     # the reference's own, taken out of each RMSE as in figures.py
    exposure = 1.0 / max(float(np.percentile(ref.mean(-1), 98)), 1e-12)
    axes = fig.subplots(len(runs), len(budgets) + 1, squeeze=False)
    for i, (label, run) in enumerate(runs.items()):
        for k, point in enumerate(run["points"]):
            image = renders[(label, k)]["images"][0]
            axes[i, k].imshow(to_srgb8((image * exposure).astype(np.float32)))
            rel = np.sqrt(max(point["rmse_each"][0] ** 2 - noise, 0.0)) / point["reference_mean"]
            spp = "" if unit == "spp" else f" ({point['spp']} spp)"
            axes[i, k].set_title(f"{label}, {budgets[k]:g} {unit}{spp}\nrel. RMSE {rel:.1%}", fontsize=8)
        axes[i, -1].axis("off")
    axes[0, -1].axis("on")
    axes[0, -1].imshow(to_srgb8((ref * exposure).astype(np.float32)))
    axes[0, -1].set_title("reference", fontsize=8)
    for a in axes.flat:
        a.set_xticks([])
        a.set_yticks([])
    fig.suptitle(f"{report['scene']}: each run at each budget (first repetition), one exposure", fontsize=9)
    fig.tight_layout()
    return fig
