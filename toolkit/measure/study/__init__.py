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
(`repetitions`), and bias2 / se follows Student's t with R - 1 degrees of freedom (`bias2_dof`)::

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

The package, one module a step: knobs.py (the runs and their knob values), workers.py (where
the renders run: here or on a Dask cluster), calibration.py (a time budget becomes a sample
count), figures.py (the figures above), report.py (the report and its table), plots.py, runs.py
(study() itself, its steps in order) and at_equal_time.py (equal_time: the study with one
budget). Import them from here (`from toolkit.measure.study import study, format_study`).
"""
from toolkit.measure.study.calibration import CALIBRATION_SECONDS, calibrate, fit_cost, plan
from toolkit.measure.study.at_equal_time import equal_time, format_equal_time
from toolkit.measure.study.figures import (MIN_PIXEL_TEST_SAMPLES, against_samples, error_figures, fit_slope,
                                           pixel_test, point_figures, time_to_target)
from toolkit.measure.study.knobs import DEFAULT_RESOLUTION, INTEGRATOR_KNOBS, Repetition, Run, make_runs, \
    parse_knob, parse_value
from toolkit.measure.study.report import format_study, write_report
from toolkit.measure.study.runs import DEFAULT_BUDGETS, DEFAULT_REPEATS, DEFAULT_TARGET, DEFAULT_TECHNIQUES, study
from toolkit.measure.study.workers import run_repetition

__all__ = ["study", "format_study", "equal_time", "format_equal_time", "write_report", "error_figures",
           "pixel_test", "point_figures", "fit_slope", "against_samples", "time_to_target", "calibrate", "fit_cost", "plan",
           "run_repetition", "Run", "Repetition", "make_runs", "parse_knob", "parse_value",
           "DEFAULT_TECHNIQUES", "DEFAULT_BUDGETS", "DEFAULT_REPEATS", "DEFAULT_RESOLUTION", "DEFAULT_TARGET",
           "INTEGRATOR_KNOBS", "CALIBRATION_SECONDS", "MIN_PIXEL_TEST_SAMPLES"]
