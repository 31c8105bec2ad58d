"""`python -m toolkit study`: the speed-accuracy study. Error against time for each technique,
and for each value of an accuracy knob (max_depth, rr_depth, clamp, pass_spp, resolution, mlt's
chains / start / large_step), against the scene's reference.

How a time budget becomes work (so that a study can be reproduced). A short calibration per
run (technique and knob value) measures its speed: a warm-up render (kernel build and first
launches, reported apart as `warmup_seconds`), then timed renders of about an eighth and half
the largest budget fit `seconds = fixed + seconds_per_spp * spp` near the budgets. Each budget
then becomes a sample count, the `plan` written into the report. Repetition r of budget k
renders that many samples with its own seed, `seed + k * repeats + r`, so every image of a
study is independent, and the same plan with the same seeds gives the same images on any
machine or cluster (`scheduler`). The wall time of each repetition (render only: build
excluded) is measured and is the time of every figure. `spp_budgets` skips the calibration:
fixed sample counts (tests, or the plan of an earlier study).

The figures of R repetitions of one budget (images I_r, reference ref with standard error s),
per pixel j (its three channels averaged), e_rj = I_rj - ref_j:

    variance_j = sample variance of e_rj over r                   (one repetition's noise)
    bias2_j    = mean_r(e_rj)^2 - variance_j / R - s_j^2           (as in toolkit/measure/mlt_bias.py)
    mse_j      = bias2_j + variance_j                               (of one repetition)

The last two terms of bias2 remove, in expectation, the noise of the mean over repetitions and
the reference's own noise, so bias2 is unbiased (and may come out slightly below 0 when it is
~0). Each figure is the mean over pixels.

Standard errors need R >= 3. In the path tracers each pixel's samples are independent of the
other pixels' (`se_method` "pixels"): each pixel's delete-one jackknife over the repetitions,
added over the pixels, plus the reference's noise for bias2 and mse. bias2 / se is the z of the
test "no bias"; the jackknife of this quadratic figure errs on the safe side (simulated without
bias, with a few pixels 300x noisier than the rest as in the Cornell box, z has a standard
deviation of ~0.7, not 1: tests/test_study.py). The spread of bias2_j over the pixels would be
exact without bias but hides a bias that only a few pixels have (a clamped light). BDPT's
light-tracing splats and mlt's chains tie pixels together (a light path lands on several), so
there the errors are the jackknife of the whole-image figures over the repetitions
(`repetitions`), and bias2 / se follows Student's t with R - 1 degrees of freedom (`bias2_dof`).

    time           = the fastest repetition's wall time (timeit's rule: a slower repetition
                     measures whatever else the machine was doing, not the technique; on a busy
                     2-core machine a 30 ms render can take 50% longer); time_median beside it
    efficiency     = 1 / (mse * time)
    slope          = d log(RMSE) / d log(time), a weighted least-squares line through the budgets
                     (weights from the standard errors of log RMSE and log time; -1/2 for an
                     unbiased, consistent estimator whose time grows with its samples)
    time to target = time at which relative RMSE (RMSE / mean of the reference) falls to
                     `target` (default 5%): interpolated between the budgets that bracket it
                     ("measured"), else along the fitted slope ("extrapolated"), or None when a
                     significant bias alone exceeds it ("unreachable")
    pixel_test     = the reference z-test (toolkit/measure/reference.py) of the mean of the repetitions,
                     pixel by pixel with each render's own standard error: "no bias", tested far
                     more strongly than by bias2's z, which the noisiest pixels dominate (where
                     the renders hold 1024 samples per pixel, or 10 degrees of freedom from passes)
    hard           = the same over the 10% hardest pixels (reference.hard_pixels), relative to
                     their own mean.

`import toolkit` makes `toolkit.measure.study` the function study() below; import the helpers by name
(`from toolkit.measure.study import format_study`).
"""
import dataclasses
import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolkit.api import as_scene, render
from toolkit.measure.reference import hard_pixels
from toolkit.techniques import family
from toolkit.measure.reference import reference_at, reference_problem
from toolkit.core.scene import Scene, check_scene, load_scene
from toolkit.core.validate import LIMITS, InputError, finite_number, whole_number

DEFAULT_TECHNIQUES = ("pt_naive", "pt_compact_regen", "bdpt_parallel_connect", "mlt")
DEFAULT_BUDGETS = (0.1, 0.2, 0.4, 0.8, 1.6)     # seconds per repetition: the default run takes ~1 minute
DEFAULT_REPEATS = 3
DEFAULT_RESOLUTION = (32, 32)                  # every bundled reference averages down to it
DEFAULT_TARGET = 0.05
INTEGRATOR_KNOBS = ("max_depth", "rr_depth", "clamp")   # scene integrator settings (FORMAT.md)
CALIBRATION_SECONDS = (0.05, 2.0)              # the longest probe: half the largest budget, within these


@dataclass(frozen=True)
class Run:
    """One curve of the study: a technique with its options, integrator settings and resolution."""
    label: str
    technique: str
    options: tuple = ()          # (name, value) pairs: technique options
    integrator: tuple = ()       # (name, value) pairs: overrides of the scene's integrator settings
    resolution: tuple = DEFAULT_RESOLUTION
    knob: tuple = None           # (name, value) for a knob sweep


@dataclass
class Repetition:
    """What a worker needs to render one repetition: nothing OpenCL, only names and numbers
    (a Dask worker makes its own context on its own device)."""
    scene: object                # scene folder (str), or a Scene made in Python (pickled)
    run: Run
    spp: int
    seed: int
    device: str = None
    bvh: str = "wide"


# -- the work: one repetition, and the calibration of a run ----------------------------------

_scenes = {}      # per process: a worker loads each scene once
_warm = set()     # per process: runs whose kernels are built and launched once


def _scene_of(job):
    scene = job.scene
    if isinstance(scene, str):
        if scene not in _scenes:
            _scenes[scene] = load_scene(scene)
        scene = _scenes[scene]
    if job.run.integrator:
        scene = dataclasses.replace(scene, **dict(job.run.integrator))
    return scene


def _render(job, spp, seed):
    scene = _scene_of(job)
    key = (job.scene if isinstance(job.scene, str) else id(job.scene), job.run, job.device, job.bvh)
    if key not in _warm:
        # Warm-up, untimed: the kernel build and the first launches (PoCL compiles there).
        render(scene, technique=job.run.technique, spp=1, seed=seed, resolution=job.run.resolution,
               device=job.device, count_simd=False, options=dict(job.run.options), bvh=job.bvh)
        _warm.add(key)
    return render(scene, technique=job.run.technique, spp=spp, seed=seed, resolution=job.run.resolution,
                  device=job.device, count_simd=False, options=dict(job.run.options), bvh=job.bvh)


def run_repetition(job):
    """Render one repetition: {"image" (H, W, 3) float64, "stderr" (its own standard error, from its
    samples or passes), "dof" (None: from samples), "seconds" (render only), "device"}."""
    result = _render(job, job.spp, job.seed)
    return {"image": result.image, "stderr": result.stderr, "dof": result.stats["degrees_of_freedom"],
            "seconds": result.stats["seconds"], "device": result.stats["device"]}


def calibrate(job, seconds):
    """A run's speed near the budgets: a warm-up (build and first launches, timed apart), a render
    of 1 spp for a first guess, then renders of about seconds / 4 and `seconds` (`seconds` is half
    the largest budget), each twice, the faster counted; up to two more aimed at `seconds` while
    the last one took under 0.7 or over 1.4 times it. The line through the last two, seconds = fixed + seconds_per_spp * spp,
    is the cost model: near the budgets, where it is used (a short render costs more per sample:
    a BDPT pass ends with a drain of its longest paths, mlt starts its chains)."""
    start = time.perf_counter()
    _render(job, 1, job.seed)                 # also warms up, the first time in this process
    warmup = time.perf_counter() - start
    probes = [(1, _render(job, 1, job.seed).stats["seconds"])]
    for share in (0.25, 1.0, 1.0, 1.0):
        if share == 1.0 and len(probes) > 2 and 0.7 <= probes[-1][1] / seconds <= 1.4:
            break      # the last probe landed near `seconds`: the line through the last two holds there
        # Else probe again: a first guess from 1 spp can be far off where a short render costs more
        # than its share (mlt's start = pool: the candidates' cost grows with the chains, which
        # grow with spp until every chain runs), and a line through such probes is too steep.
        fixed, per_spp = _fit_cost(probes[-2:])
        floor = probes[-1][0] + 1 if len(probes) < 3 else 1
        spp = int(min(max(floor, (share * seconds - fixed) / per_spp), LIMITS["spp"][1]))
        # The faster of two: a busy moment of the machine only ever adds time.
        probes.append((spp, min(_render(job, spp, job.seed).stats["seconds"] for _ in range(2))))
    fixed, per_spp = _fit_cost(probes[-2:])
    pixels = job.run.resolution[0] * job.run.resolution[1]
    return {"warmup_seconds": warmup, "probes": [list(p) for p in probes], "fixed_seconds": fixed,
            "seconds_per_spp": per_spp, "samples_per_second": pixels / per_spp}


def _fit_cost(probes):
    """(fixed, per_spp) of the line seconds = fixed + per_spp * spp through the probes (least
    squares; a noisy fit that would make the fixed cost negative or the cost per spp not positive
    is replaced by a line through the origin and the largest probe)."""
    spp, t = (np.array(c, dtype=float) for c in zip(*probes))
    if len(probes) >= 2 and np.ptp(spp) > 0:
        per_spp, fixed = np.polyfit(spp, t, 1)
        if per_spp > 0 and fixed >= 0:
            return float(fixed), float(per_spp)
    k = int(np.argmax(spp))
    return 0.0, float(max(t[k], 1e-6) / spp[k])


def plan(calibration, budgets):
    """Samples per pixel for each time budget, from a run's calibration."""
    return [int(min(max(1, round((b - calibration["fixed_seconds"]) / calibration["seconds_per_spp"])),
                    LIMITS["spp"][1])) for b in budgets]


def _map(function, items, scheduler, progress, what):
    """function(item) for every item: here, in order, or on the Dask cluster at `scheduler`."""
    if scheduler is None:
        bar = None
        if progress:
            from tqdm.auto import tqdm
            bar = tqdm(total=len(items), desc=what, unit="render", file=sys.stderr, leave=False)
        out = []
        for item in items:
            out.append(function(*item))
            if bar is not None:
                bar.update(1)
        if bar is not None:
            bar.close()
        return out
    try:
        from distributed import Client
    except ImportError:
        raise InputError('--scheduler needs dask.distributed: pip install ".[cluster]"') from None
    with Client(scheduler) as client:       # an address, or a cluster object from Python
        futures = [client.submit(function, *item, pure=False) for item in items]
        if progress:
            from distributed import progress as dask_progress
            dask_progress(futures)
        return client.gather(futures)


# -- the figures -----------------------------------------------------------------------------

def error_figures(images, ref, ref_err, se_method="pixels"):
    """mse, bias2, variance (of one repetition, absolute) with standard errors, from R images
    (R, N, 3) of N pixels against ref (N, 3) with its standard error (see the module docstring)."""
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
    from toolkit.measure.reference import MIN_DEGREES_OF_FREEDOM, z_test
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


def time_to_target(points, fit, target):
    """Seconds to reach relative RMSE `target`, and how it was found (see the module docstring)."""
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


# -- the study -------------------------------------------------------------------------------

def parse_value(text):
    """A knob value from the command line: none/null, a whole number, a number, or a word."""
    text = text.strip()
    if text.lower() in ("none", "null", "off"):
        return None
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def parse_knob(text):
    """"max_depth=2,3,4,-1" -> ("max_depth", [2, 3, 4, -1]); resolution values are WxH."""
    if not isinstance(text, str) or "=" not in text:
        raise InputError(f"--knob must be NAME=V1,V2,... (like max_depth=2,3,4,-1), got {text!r}")
    name, values = text.split("=", 1)
    name = name.strip()
    items = [v for v in values.split(",") if v.strip()]
    if not items:
        raise InputError(f"--knob {name}: no values given")
    if name == "resolution":
        return name, [_resolution_value(v) for v in items]
    return name, [parse_value(v) for v in items]


def _resolution_value(text):
    try:
        w, h = (int(x) for x in str(text).lower().split("x"))
        if w >= 1 and h >= 1:
            return (w, h)
    except ValueError:
        pass
    raise InputError(f"--knob resolution: expected WIDTHxHEIGHT like 16x16, got {text!r}")


def make_runs(techniques, knob, resolution):
    """The study's curves: each technique, or each technique x knob value."""
    from toolkit.api import _options
    from toolkit.techniques import get_technique
    runs = []
    for name in techniques:
        cls, _ = get_technique(name)
        if knob is None:
            runs.append(Run(name, name, resolution=tuple(resolution)))
            continue
        knob_name, values = knob
        for value in values:
            label = f"{name} {knob_name}={'x'.join(map(str, value)) if knob_name == 'resolution' else value}"
            if knob_name in INTEGRATOR_KNOBS:
                runs.append(Run(label, name, integrator=((knob_name, value),), resolution=tuple(resolution),
                                knob=(knob_name, value)))
            elif knob_name == "resolution":
                runs.append(Run(label, name, resolution=tuple(value), knob=(knob_name, value)))
            else:
                _options(cls, {knob_name: value})     # an option the technique takes, else a clear error
                runs.append(Run(label, name, options=((knob_name, value),), resolution=tuple(resolution),
                                knob=(knob_name, value)))
    return runs


def _check_run(scene, run):
    """Before any work: the run's scene settings within limits and a reference to compare with."""
    if run.integrator:
        changed = dataclasses.replace(scene, **dict(run.integrator))
        for key, value in run.integrator:
            if key in ("max_depth", "rr_depth") and (isinstance(value, bool) or not isinstance(value, int)):
                raise InputError(f"knob {key} must be a whole number, got {value!r}")
        check_scene(changed, f"{scene.name} with {run.label}")
        if changed.max_depth < 0 and changed.rr_depth < 0:
            raise InputError(f"{run.label}: max_depth -1 (unbounded) needs Russian roulette (rr_depth >= 0)")
    width, height = run.resolution
    if reference_at(scene, width, height)[0] is None:
        raise InputError(f"{scene.name}: no reference to compare with at {width}x{height}: "
                         f"{reference_problem(scene, width, height) or 'the scene has none'}")


def study(scene=None, techniques=DEFAULT_TECHNIQUES, budgets=DEFAULT_BUDGETS, repeats=DEFAULT_REPEATS,
          resolution=DEFAULT_RESOLUTION, seed=0, spp_budgets=None, knob=None, target=DEFAULT_TARGET,
          scheduler=None, device=None, bvh="wide", out_dir=None, progress=False, specialization=False):
    """Error against time for each technique (and knob value) on `scene`; returns the report
    (a dict that json.dumps writes) and, with `out_dir`, writes study.json and the plots there.

    `budgets` are seconds of rendering per repetition; each is turned into a sample count by a
    calibration of each run (see the module docstring), so the renders, and with the same plan
    and seeds their images, are reproducible. `spp_budgets` instead: sample counts, a list for
    every run or {label: list}, no calibration. `repeats`: independent repetitions per budget
    (distinct seeds; at least 2 to split bias^2 from variance). `knob`: "name=v1,v2" or
    (name, [values]): max_depth, rr_depth, clamp (scene integrator settings), resolution, or a
    technique option (pass_spp; mlt's chains, start, large_step, ...). `target`: the relative
    RMSE for the time-to-target figures. `scheduler`: the address of a Dask cluster
    (dask.distributed, `pip install ".[cluster]"`) that renders the repetitions; each worker uses
    its own OpenCL device. `specialization`: also measure, on this machine, the kernels specialized
    to the scene against the general kernel for the study's techniques (samples/s ratio, uncached
    build time, binary size: toolkit.measure.specialization), under the report's "specialization".
    Returns {"runs": {label: {...}}, ...}: see format_study."""
    started = time.perf_counter()
    given = scene
    scene = as_scene(scene)
    # What a worker gets: the scene file's path, or a Scene made in Python itself (pickled).
    shipped = given if isinstance(given, Scene) else str(scene.path)
    if isinstance(techniques, str):
        techniques = [t.strip() for t in techniques.split(",") if t.strip()]
    if not techniques:
        raise InputError("no technique given")
    repeats = whole_number("study.repeats", repeats, "repeats")
    seed = whole_number("seed", seed)
    target = finite_number("study.target", target, "target")
    if isinstance(knob, str):
        knob = parse_knob(knob)
    runs = make_runs(techniques, knob, resolution)
    labels = [r.label for r in runs]
    if len(set(labels)) != len(labels):
        raise InputError(f"a run is given twice: {', '.join(labels)}")
    for run in runs:
        _check_run(scene, run)
    if spp_budgets is not None:
        per_run = spp_budgets if isinstance(spp_budgets, dict) else {label: spp_budgets for label in labels}
        plans = {}
        for label in labels:
            if label not in per_run:
                raise InputError(f"spp_budgets has no sample counts for {label!r}")
            plans[label] = [whole_number("spp", s, "spp budget") for s in per_run[label]]
        count = len(next(iter(plans.values())))
        if any(len(p) != count for p in plans.values()):
            raise InputError("spp_budgets: every run needs the same number of budgets")
        budget_list, unit = list(next(iter(plans.values()))), "spp"
    else:
        budget_list = [finite_number("study.budget", float(b), "budget") for b in budgets]
        unit = "seconds"
        if not budget_list:
            raise InputError("no budget given")
    whole_number("seed", seed + len(budget_list) * repeats - 1, "seed + budgets x repeats - 1 (the last seed)")

    def job(run, spp, s):
        return Repetition(shipped, run, spp, s, device, bvh)

    calibration = {}
    if unit == "seconds":
        probe = min(max(max(budget_list) / 2, CALIBRATION_SECONDS[0]), CALIBRATION_SECONDS[1])
        cal_seed = (seed + (1 << 31)) % (1 << 32)       # apart from the study's seeds
        results = _map(calibrate, [(job(run, 1, cal_seed), probe) for run in runs], scheduler, progress,
                       "calibration")
        calibration = dict(zip(labels, results))
        plans = {label: plan(calibration[label], budget_list) for label in labels}
    # Interleaved (repetition, budget, run): a slow moment of the machine does not favour one run.
    items = [(r, k, run) for r in range(repeats) for k in range(len(budget_list)) for run in runs]
    results = _map(run_repetition, [(job(run, plans[run.label][k], seed + k * repeats + r),)
                                    for r, k, run in items], scheduler, progress, "study")
    images, stderrs, dofs, seconds, device_name = {}, {}, {}, {}, None
    for (r, k, run), res in zip(items, results):
        images.setdefault((run.label, k), []).append(res["image"])
        stderrs.setdefault((run.label, k), []).append(res["stderr"])
        dofs.setdefault((run.label, k), []).append(res["dof"])
        seconds.setdefault((run.label, k), []).append(res["seconds"])
        device_name = res["device"]

    report = {"scene": scene.name, "resolution": list(resolution), "device": device_name,
              "budget_unit": unit, "budgets": budget_list, "repeats": repeats, "seed": seed,
              "seeds": "repetition r of budget k: seed + k * repeats + r", "target": target,
              "scheduler": scheduler if isinstance(scheduler, (str, type(None))) else str(scheduler),
              "knob": None if knob is None else {"name": knob[0], "values": [
                  list(v) if isinstance(v, tuple) else v for v in knob[1]]},
              "runs": {}}
    for run in runs:
        width, height = run.resolution
        ref, ref_err = reference_at(scene, width, height)
        hard = hard_pixels(ref, ref_err)
        whole = np.ones(ref.shape[:2], bool)
        # Pixels are independent in the path tracers; BDPT's light-tracing splats and mlt's chains tie
        # them together, so there the jackknife works on whole images (see the module docstring).
        se_method = "pixels" if family(run.technique) == "pt" else "repetitions"
        points, hard_points = [], []
        for k, budget in enumerate(budget_list):
            imgs, secs = images[(run.label, k)], seconds[(run.label, k)]
            head = {"budget": budget, "spp": plans[run.label][k], "seconds": secs,
                    "seeds": [seed + k * repeats + r for r in range(repeats)]}
            points.append({**head, **point_figures(imgs, secs, ref, ref_err, whole, se_method,
                                                   stderrs[(run.label, k)], dofs[(run.label, k)],
                                                   plans[run.label][k])})
            hard_points.append({**head, **point_figures(imgs, secs, ref, ref_err, hard, se_method)})
        fit, hard_fit = fit_slope(points), fit_slope(hard_points)
        report["runs"][run.label] = {
            "technique": run.technique, "family": family(run.technique), "options": dict(run.options),
            "integrator": dict(run.integrator), "resolution": list(run.resolution),
            "knob": None if run.knob is None else {"name": run.knob[0], "value": (
                list(run.knob[1]) if isinstance(run.knob[1], tuple) else run.knob[1])},
            "calibration": calibration.get(run.label), "plan": plans[run.label], "se_method": se_method,
            "points": points, "slope": fit, "time_to_target": time_to_target(points, fit, target),
            "hard": {"points": hard_points, "slope": hard_fit,
                     "time_to_target": time_to_target(hard_points, hard_fit, target)},
        }
    if specialization:   # on this machine, not on the cluster: a ratio of two local measurements
        from toolkit.measure.specialization import measure_specialization
        names = list(dict.fromkeys(run.technique for run in runs))
        report["specialization"] = measure_specialization(scene, names, resolution=tuple(resolution),
                                                          device=device, bvh=bvh)
    report["study_seconds"] = time.perf_counter() - started
    if out_dir is not None:
        report["plots"] = save_plots(report, images, scene, Path(out_dir))
        write_report(report, Path(out_dir) / "study.json")
    return report


def write_report(report, path):
    from toolkit.core.images import write_atomically
    text = json.dumps(report, indent=1, default=_json_default)
    return write_atomically(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def _json_default(x):
    if isinstance(x, (np.integer, np.floating)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)


# -- output: the table and the plots ---------------------------------------------------------

def _pm(value, se, fmt):
    if value is None:
        return "-"
    return f"{value:{fmt}}" + (f"±{se:{fmt}}" if se is not None else "")


def format_study(report):
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
        lines.append(f"{label:<34}{_slope(run['slope']):>14} {_ttt(run['time_to_target']):>25}"
                     f"{_slope(run['hard']['slope']):>20} {_ttt(run['hard']['time_to_target']):>25}{rate:>12}{warm:>10}")
    if report.get("specialization"):
        from toolkit.measure.specialization import format_specialization
        lines += ["", format_specialization(report["specialization"])]
    if report.get("plots"):
        lines.append("plots: " + ", ".join(report["plots"].values()))
    return "\n".join(lines)


def _slope(fit):
    return "-" if fit is None else f"{fit['slope']:.2f}±{fit['se']:.2f}"


def _ttt(t):
    if t["seconds"] is None:
        return t["how"]
    se = f"±{t['se']:.2g}" if t.get("se") else ""
    return f"{t['seconds']:.3g}{se} {t['how']}"


def save_plots(report, images, scene, out_dir):
    """RMSE against time (log-log, with the 1/sqrt(t) guide), bias^2 and variance stacked per run
    at the largest budget, and an image strip with false-colour error at equal time. Each file is
    written to a temporary file and renamed over the old one."""
    from matplotlib.figure import Figure
    from toolkit.core.images import to_srgb8, write_atomically
    out_dir.mkdir(parents=True, exist_ok=True)
    name = report["scene"]
    paths = {}
    runs = report["runs"]

    fig = Figure(figsize=(7.5, 5))
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
                    label=f"{label} (slope {_slope(run['slope'])})")
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
           title=f"{name}: error against time, {report['repeats']} repetitions per point")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    fig.tight_layout()
    paths["rmse_vs_time"] = _save(fig, out_dir / f"{name}_study_rmse_vs_time.png", write_atomically)

    labels = list(runs)
    last = [runs[l]["points"][-1] for l in labels]
    if all(p["bias2"] is not None for p in last):
        fig = Figure(figsize=(max(5.0, 1.1 * len(labels) + 2), 4.8))
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
               title=f"{name}: bias² and variance at the largest budget "
                     f"({budget:g} {'s' if report['budget_unit'] == 'seconds' else 'spp'})")
        ax.legend()
        ax.grid(alpha=0.3, axis="y")
        fig.tight_layout()
        paths["bias_variance"] = _save(fig, out_dir / f"{name}_study_bias_variance.png", write_atomically)

    k = len(report["budgets"]) - 1
    shown = {l: images[(l, k)][0] for l in labels}
    refs = {l: reference_at(scene, *runs[l]["resolution"])[0] for l in labels}
    errors = {l: np.abs(shown[l] - refs[l]).mean(-1) for l in labels}
    vmax = max(float(np.percentile(e, 99)) for e in errors.values()) or 1.0
    fig = Figure(figsize=(2.6 * len(labels) + 1, 5.6))
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
    fig.suptitle(f"{name}: equal time, the largest budget, first repetition", fontsize=9)
    paths["image_strip"] = _save(fig, out_dir / f"{name}_study_image_strip.png", write_atomically)
    return paths


def _save(fig, path, write_atomically):
    write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=100, format="png"))
    return str(path)


def equal_time(scene, techniques, seconds, resolution=(32, 32), seed=0, device=None, bvh="wide", repeats=1):
    """Each technique renders for about `seconds` of wall time, whatever its speed: the speed-accuracy
    study (toolkit/measure/study.py) with one time budget. Its calibration turns the time into a sample
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
