"""The study's report: the figures of every run at every budget gathered into one dict (which
json.dumps writes to study.json), and the table that `python -m toolkit study` prints."""
import json
from pathlib import Path

import numpy as np

from toolkit.core.images import write_atomically
from toolkit.measure.reference import hard_pixels, reference_at
from toolkit.measure.specialization import format_specialization
from toolkit.measure.study.figures import fit_slope, point_figures, time_to_target
from toolkit.techniques import family


def _listed(value):
    """A knob value as JSON writes it (a resolution is a pair)."""
    return list(value) if isinstance(value, tuple) else value


def report_head(scene, resolution, device_name, unit, budgets, repeats, seed, target, scheduler, knob):
    """The report's settings: what a reader needs to reproduce the study."""
    return {"scene": scene.name, "resolution": list(resolution), "device": device_name,
            "budget_unit": unit, "budgets": budgets, "repeats": repeats, "seed": seed,
            "seeds": "repetition r of budget k: seed + k * repeats + r", "target": target,
            "scheduler": scheduler if isinstance(scheduler, (str, type(None))) else str(scheduler),
            "knob": None if knob is None else {"name": knob[0], "values": [_listed(v) for v in knob[1]]},
            "runs": {}}


def run_report(scene, run, renders, plan, calibration, budgets, repeats, seed, target):
    """One run's figures at every budget, over all pixels and over the hardest ones. `renders`
    maps (label, budget index) to {"images", "stderrs", "dofs", "seconds"} of its repetitions."""
    ref, ref_err = reference_at(scene, *run.resolution)
    hard = hard_pixels(ref, ref_err)
    whole = np.ones(ref.shape[:2], bool)
    # Pixels are independent in the path tracers; BDPT's light-tracing splats and mlt's chains tie
    # them together, so there the jackknife works on whole images (see the package docstring).
    se_method = "pixels" if family(run.technique) == "pt" else "repetitions"
    points, hard_points = [], []
    for k, budget in enumerate(budgets):
        got = renders[(run.label, k)]
        head = {"budget": budget, "spp": plan[k], "seconds": got["seconds"],
                "seeds": [seed + k * repeats + r for r in range(repeats)]}
        points.append({**head, **point_figures(got["images"], got["seconds"], ref, ref_err, whole, se_method,
                                               got["stderrs"], got["dofs"], plan[k])})
        hard_points.append({**head, **point_figures(got["images"], got["seconds"], ref, ref_err, hard, se_method)})
    fit, hard_fit = fit_slope(points), fit_slope(hard_points)
    return {
        "technique": run.technique, "family": family(run.technique), "options": dict(run.options),
        "integrator": dict(run.integrator), "resolution": list(run.resolution),
        "knob": None if run.knob is None else {"name": run.knob[0], "value": _listed(run.knob[1])},
        "calibration": calibration, "plan": plan, "se_method": se_method,
        "points": points, "slope": fit, "time_to_target": time_to_target(points, fit, target),
        "hard": {"points": hard_points, "slope": hard_fit,
                 "time_to_target": time_to_target(hard_points, hard_fit, target)},
    }


def write_report(report, path):
    """Write the study's report (every figure) as JSON to `path`, through a temporary file renamed
    over it; returns the path."""
    text = json.dumps(report, indent=1, default=_json_default)
    return write_atomically(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def _json_default(x):
    if isinstance(x, (np.integer, np.floating)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)


# -- the table ---------------------------------------------------------------------------------

def _pm(value, se, fmt):
    if value is None:
        return "-"
    return f"{value:{fmt}}" + (f"±{se:{fmt}}" if se is not None else "")


def format_study(report):
    """The study's report as the table `python -m toolkit study` prints: per technique (or knob
    value) and budget, the time, bias², variance, efficiency, slope and time to the target."""
    unit = "s" if report["budget_unit"] == "seconds" else "spp"
    lines = [f"study: {report['scene']}, {report['repeats']} repetitions per budget on {report['device']}; "
             + ("time budgets turned into sample counts by a calibration (the plan: spp column)"
                if unit == "s" else "fixed sample counts (no calibration)"),
             "relative figures: RMSE / reference mean, bias^2 and variance / reference mean^2; ± one standard error"]
    head = (f"{'run':<34}{'budget':>8}{'spp':>7}{'time s':>8}{'rel RMSE':>18}{'bias^2 (rel)':>22}"
            f"{'z':>7}{'variance (rel)':>22}{'efficiency':>12}")
    lines += [head, "-" * len(head)]
    for label, run in report["runs"].items():
        for p in run["points"]:
            s = p["reference_mean"] ** 2
            rel = lambda v: None if v is None else v / s   # noqa: E731
            lines.append(
                f"{label:<34}{p['budget']:>8g}{p['spp']:>7}{p['time']:>8.3f}"
                f"{_pm(p['relative_rmse'], p['relative_rmse_se'], '.4f'):>18}"
                f"{_pm(rel(p['bias2']), rel(p['bias2_se']), '.2e'):>22}"
                f"{(format(p['bias2_z'], '.1f') if p.get('bias2_z') is not None else '-'):>7}"
                f"{_pm(rel(p['variance']), rel(p['variance_se']), '.2e'):>22}"
                f"{(format(p['efficiency'], '.3g') if p['efficiency'] else '-'):>12}")
    lines.append("")
    head = (f"{'run':<34}{'slope':>14}{'time to ' + format(report['target'], '.0%') + ' s':>26}"
            f"{'hard pixels: slope':>20}{'time s':>26}{'samples/s':>12}{'warm-up s':>10}")
    lines += [head, "-" * len(head)]
    for label, run in report["runs"].items():
        cal = run["calibration"] or {}
        rate = f"{cal['samples_per_second']:,.0f}" if cal else "-"
        warm = f"{cal['warmup_seconds']:.2f}" if cal else "-"
        lines.append(f"{label:<34}{slope_text(run['slope']):>14} {target_text(run['time_to_target']):>25}"
                     f"{slope_text(run['hard']['slope']):>20} {target_text(run['hard']['time_to_target']):>25}{rate:>12}{warm:>10}")
    if report.get("specialization"):
        lines += ["", format_specialization(report["specialization"])]
    if report.get("plots"):
        lines.append("plots: " + ", ".join(report["plots"].values()))
    return "\n".join(lines)


def slope_text(fit):
    """A fitted slope with its standard error, as the table and the plot show it."""
    return "-" if fit is None else f"{fit['slope']:.2f}±{fit['se']:.2f}"


def target_text(t):
    """A time to target with its standard error and how it was found."""
    if t["seconds"] is None:
        return t["how"]
    se = f"±{t['se']:.2g}" if t.get("se") else ""
    return f"{t['seconds']:.3g}{se} {t['how']}"


