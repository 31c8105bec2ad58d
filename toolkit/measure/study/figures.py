"""The figures of one budget: from R repetitions against the reference, mse, bias^2 and variance
with their standard errors (the package docstring gives the formulas), the pixel z-test, the time
and efficiency; then over the budgets the slope of log RMSE against log time and the time to reach
the target error."""
import math

import numpy as np

from toolkit.measure.reference import MIN_DEGREES_OF_FREEDOM, z_test


def error_figures(images, ref, ref_err, se_method="pixels"):
    """mse, bias2, variance (of one repetition, absolute) with standard errors, from R images
    (R, N, 3) of N pixels against ref (N, 3) with its standard error (see the package docstring)."""
    images = np.asarray(images, np.float64)
    reps, n = images.shape[0], images.shape[1]
    err = images - ref
    rmse_each = np.sqrt((err ** 2).mean(axis=(1, 2)))

    def split(e):
        r = len(e)
        if r < 2:    # no spread to split with: the mean squared error less the reference's noise
            mse = ((e[0] ** 2) - ref_err ** 2).mean(-1)
            return mse, None, None
        v = e.var(0, ddof=1)
        b = e.mean(0) ** 2 - v / r - ref_err ** 2
        return (b + v).mean(-1), b.mean(-1), v.mean(-1)

    per_pixel = split(err)
    out = {"repetitions": reps, "pixels": n, "rmse_each": rmse_each.tolist(), "se_method": se_method}
    names = ("mse", "bias2", "variance")
    for name, x in zip(names, per_pixel):
        out[name] = None if x is None else float(x.mean())
        out[name + "_se"] = None
    if reps >= 3:
        # Delete-one jackknife over the repetitions, per pixel: (R, 3 figures, N).
        loo = np.array([split(np.delete(err, i, 0)) for i in range(reps)], dtype=float)
        if se_method == "pixels":      # independent pixels: the pixels' jackknife variances add up
            var = (reps - 1) / reps * ((loo - loo.mean(0)) ** 2).sum(0)
            # The reference's own error is the same in every repetition, so the jackknife cannot see
            # it: its share of bias2_j's variance for normal errors, 2 s^4 + 4 bias^2 s^2, is added.
            m = err.mean(0)
            bias2_c = np.maximum(m ** 2 - err.var(0, ddof=1) / reps - ref_err ** 2, 0.0)
            ref_var = (2 * ref_err ** 4 + 4 * bias2_c * ref_err ** 2).sum(-1) / 9     # of a mean of 3 channels
            var[0] += ref_var
            var[1] += ref_var
            se = np.sqrt(var.sum(-1)) / n
        else:                          # pixels tied together: the jackknife of the whole-image means
            whole = loo.mean(-1)
            se = np.sqrt((reps - 1) / reps * ((whole - whole.mean(0)) ** 2).sum(0))
        for name, value in zip(names, se):
            out[name + "_se"] = float(value)
    elif n > 1:                        # too few repetitions: the spread over pixels (an upper bound)
        for name, x in zip(names, per_pixel):
            if x is not None:
                out[name + "_se"] = float(x.std(ddof=1) / math.sqrt(n))
    if out["bias2"] is not None and out["bias2_se"]:
        out["bias2_z"] = out["bias2"] / out["bias2_se"]
        # A jackknife over R whole images: Student's t with R - 1 degrees of freedom; per pixel: normal.
        out["bias2_dof"] = reps - 1 if se_method == "repetitions" else None
    return out


MIN_PIXEL_TEST_SAMPLES = 1024  # per pixel over the repetitions: with fewer, a pixel that the light covers in part
#                                may show no spread at all, and its mean is far from normal


def pixel_test(images, stderrs, dofs, ref, ref_err, samples, alpha=0.01):
    """The z-test of toolkit.measure.reference.z_test on the mean of the repetitions, pixel by pixel, with
    each render's own standard error (its samples, or its passes: Student's t), Bonferroni-
    corrected over the pixels: a far stronger test of "no bias" than bias2's z, which the noisiest
    pixels dominate. None where the renders carry too few passes for a t-test (or no error: mlt),
    or too few samples (`samples` per pixel over the repetitions) for a normal mean."""
    reps = len(images)
    dof = None if any(d is None for d in dofs) else int(sum(dofs))
    if (dof is not None and dof < MIN_DEGREES_OF_FREEDOM) or not np.any(stderrs) \
            or (dof is None and samples < MIN_PIXEL_TEST_SAMPLES):
        return None
    stderr = np.sqrt((np.asarray(stderrs) ** 2).sum(0)) / reps
    test = z_test(np.mean(images, 0), stderr, ref, ref_err, alpha=alpha, dof=dof)
    return {"passed": test.passed, "alpha": alpha, "min_p": test.min_p, "threshold_p": test.threshold_p,
            "worst_z": test.worst_z, "mean_abs_z": test.mean_abs_z, "dof": dof}


def point_figures(images, seconds, ref, ref_err, mask, se_method, stderrs=None, dofs=None, spp=None):
    """Every figure of one budget, over the pixels of `mask` (H, W bool)."""
    fig = error_figures(np.asarray(images)[:, mask], ref[mask], ref_err[mask], se_method)
    if stderrs is not None:
        fig["pixel_test"] = pixel_test(np.asarray(images)[:, mask], np.asarray(stderrs)[:, mask], dofs,
                                       ref[mask], ref_err[mask], samples=spp * len(images))
    mean = float(ref[mask].mean())
    seconds = np.asarray(seconds, np.float64)
    t = float(seconds.min())
    # Its spread from the median absolute deviation (1.4826 MAD estimates sigma for a normal
    # spread), which one disturbed repetition does not inflate.
    mad = float(np.median(np.abs(seconds - np.median(seconds))))
    t_se = 1.4826 * mad / math.sqrt(len(seconds)) if len(seconds) > 1 else None
    fig.update(time=t, time_se=t_se, time_median=float(np.median(seconds)), reference_mean=mean)
    mse, se = fig["mse"], fig["mse_se"]
    rmse = math.sqrt(max(mse, 0.0))
    fig["rmse"] = rmse
    fig["relative_rmse"] = rmse / mean if mean > 0 else None
    fig["relative_rmse_se"] = (se / (2 * rmse * mean) if se is not None and rmse > 0 and mean > 0 else None)
    fig["efficiency"] = 1.0 / (mse * t) if mse > 0 and t > 0 else None
    if fig["efficiency"] is not None and se is not None:
        rel = math.hypot(se / mse, (t_se or 0.0) / t)
        fig["efficiency_se"] = fig["efficiency"] * rel
    else:
        fig["efficiency_se"] = None
    return fig


def fit_slope(points, nominal=-0.5):
    """Weighted least squares of log RMSE against log time over the budgets. Each point's weight
    is 1 / (var(log RMSE) + slope^2 var(log time)): var(log RMSE) = (se(mse) / (2 mse))^2 and
    var(log time) = (se(time) / time)^2, so noisy timings count less. Iterated from `nominal`.
    The standard error sqrt(1 / sum w (x - mean x)^2) is scaled by sqrt(chi^2 / dof) when the
    points scatter more than their errors say (a curve that is not a straight line)."""
    pts = [(math.log(p["time"]), 0.5 * math.log(p["mse"]), (p["time_se"] or 0.0) / p["time"],
            p["mse_se"] / (2 * p["mse"])) for p in points
           if p["mse"] is not None and p["mse"] > 0 and p["time"] > 0 and p["mse_se"]]
    if len(pts) < 2:
        return None
    x, y, sx, sy = (np.array(c) for c in zip(*pts))
    slope = nominal
    for _ in range(4):
        w = 1.0 / (sy ** 2 + slope ** 2 * sx ** 2)
        xm, ym = (w * x).sum() / w.sum(), (w * y).sum() / w.sum()
        sxx = (w * (x - xm) ** 2).sum()
        if sxx <= 0:
            return None
        slope = float((w * (x - xm) * (y - ym)).sum() / sxx)
    chi2 = float((w * (y - ym - slope * (x - xm)) ** 2).sum())
    dof = len(pts) - 2
    scale = math.sqrt(max(1.0, chi2 / dof)) if dof > 0 else 1.0
    return {"slope": slope, "se": float(scale / math.sqrt(sxx)), "log_time_mean": float(xm),
            "log_rmse_mean": float(ym), "chi2": chi2, "dof": dof, "points": len(pts)}


def against_samples(points):
    """The same points with samples per pixel as the x axis (time_se 0): the renders use fixed
    seeds, so fit_slope of these depends on the estimator alone, not on how busy the machine was."""
    return [{**p, "time": float(p["spp"]), "time_se": 0.0} for p in points]


def time_to_target(points, fit, target):
    """Seconds to reach relative RMSE `target`, and how it was found (see the package docstring)."""
    pts = sorted((p for p in points if p["relative_rmse"]), key=lambda p: p["time"])
    if not pts:
        return {"seconds": None, "how": "no figures"}
    last = pts[-1]
    mean = last["reference_mean"]
    if last["bias2"] is not None and last["bias2_se"] and last["bias2"] > 3 * last["bias2_se"] \
            and math.sqrt(last["bias2"]) / mean >= target:
        return {"seconds": None, "how": "unreachable",
                "why": f"the bias alone is {math.sqrt(last['bias2']) / mean:.3g} of the mean, above the target"}
    for a, b in zip(pts, pts[1:]):
        if a["relative_rmse"] >= target >= b["relative_rmse"] and a["relative_rmse"] > b["relative_rmse"]:
            u = math.log(a["relative_rmse"] / target) / math.log(a["relative_rmse"] / b["relative_rmse"])
            seconds = math.exp(math.log(a["time"]) + u * math.log(b["time"] / a["time"]))
            return {"seconds": seconds, "how": "measured", "se": _time_se(seconds, a, fit)}
    if fit is None or fit["slope"] >= 0:
        return {"seconds": None, "how": "not converging", "why": "the RMSE does not fall with time"}
    # Along the fitted line log RMSE = ym + slope (log t - xm), RMSE relative to the mean.
    log_t = fit["log_time_mean"] + (math.log(target * mean) - fit["log_rmse_mean"]) / fit["slope"]
    seconds = math.exp(log_t)
    nearest = pts[0] if target > pts[0]["relative_rmse"] else last
    return {"seconds": seconds, "how": "extrapolated", "se": _time_se(seconds, nearest, fit)}


def _time_se(seconds, point, fit):
    """Delta method: an error d in log RMSE moves log t by d / |slope|."""
    if fit is None or not point["relative_rmse_se"]:
        return None
    return seconds * point["relative_rmse_se"] / point["relative_rmse"] / abs(fit["slope"])
