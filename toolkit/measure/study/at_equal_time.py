"""Equal time: each technique renders for about the same wall time (the study with one budget),
and the RMSE it reaches then, over the whole image and over the hardest pixels."""
from toolkit.measure.study.runs import study
from toolkit.techniques import family


def equal_time(scene, techniques, seconds, resolution=(32, 32), seed=0, device=None, bvh="wide", repeats=1):
    """Each technique renders for about `seconds` of wall time, whatever its speed: the speed-accuracy
    study (toolkit/measure/study/) with one time budget. Its calibration turns the time into a sample
    count per technique (mlt renders it as one run of its chains, paying its start once).
    Returns {technique: {"spp", "seconds", "rmse", "rmse_hard_pixels"}} against the scene's
    reference: the first repetition's RMSE (over the 10% hardest pixels for the last)."""
    report = study(scene, list(techniques), budgets=[seconds], repeats=repeats, resolution=resolution, seed=seed,
                   device=device, bvh=bvh)
    out = {}
    for name in techniques:
        run = report["runs"][name]
        point, hard = run["points"][0], run["hard"]["points"][0]
        out[name] = {"spp": point["spp"], "seconds": point["seconds"][0], "rmse": point["rmse_each"][0],
                     "rmse_hard_pixels": hard["rmse_each"][0]}
    return out


def format_equal_time(report, seconds):
    """The table of `bench --equal-time`: each technique's RMSE after about `seconds` of rendering,
    over the whole image and over its hardest pixels."""
    lines = [f"equal time (~{seconds:g} s each): RMSE against the reference, over the whole image and over "
             f"the 10% pixels hardest for a path tracer (largest relative error in the reference: caustics)"]
    for name, row in report.items():
        lines.append(f"  {name:<30}{row['spp']:>7} spp {row['seconds']:>7.2f} s   RMSE {row['rmse']:.5f}"
                     f"   hard pixels {row['rmse_hard_pixels']:.5f}")
    for key, label in (("rmse", "whole image"), ("rmse_hard_pixels", "hard pixels")):
        pt = [r[key] for n, r in report.items() if family(n) == "pt"]
        bd = [r[key] for n, r in report.items() if family(n) == "bdpt"]
        if pt and bd:
            lines.append(f"  best BDPT / best PT RMSE, {label}: {min(bd) / min(pt):.2f}")
    for name, row in report.items():
        if family(name) == "mlt":
            for other in ("pt", "bdpt"):
                rows = [r["rmse"] for n, r in report.items() if family(n) == other]
                if rows:
                    lines.append(f"  {name} / best {other.upper()} RMSE, whole image: {row['rmse'] / min(rows):.2f}"
                                 f" ({'MLT wins' if row['rmse'] < min(rows) else 'MLT loses'})")
    pt = {n: r for n, r in report.items() if family(n) == "pt"}
    bd = {n: r for n, r in report.items() if family(n) == "bdpt"}
    if pt and bd:
        # Squared error x samples does not depend on the time spent: what one sample is worth.
        p_name = min(pt, key=lambda n: pt[n]["rmse"])
        b_name = min(bd, key=lambda n: bd[n]["rmse"])
        p, b = pt[p_name], bd[b_name]
        cost = (b["seconds"] / b["spp"]) / (p["seconds"] / p["spp"])
        worth = (p["rmse"] ** 2 * p["spp"]) / (b["rmse"] ** 2 * b["spp"])
        lines.append(f"  one {b_name} sample costs {cost:.1f} {p_name} samples here and is worth {worth:.1f} of them "
                     f"(squared error x samples, whole image): BDPT wins at equal time where worth > cost")
    return "\n".join(lines)
