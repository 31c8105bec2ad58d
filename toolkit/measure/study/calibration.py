"""How a time budget becomes a sample count: a run's speed measured near the budgets (the cost
line seconds = fixed + seconds_per_spp * spp), then each budget read off that line (the plan)."""
import time

import numpy as np

from toolkit.core.validate import LIMITS
from toolkit.measure.study.workers import render_job

CALIBRATION_SECONDS = (0.05, 2.0)              # the longest probe: half the largest budget, within these


def calibrate(job, seconds):
    """A run's speed near the budgets: a warm-up (build and first launches, timed apart), a render
    of 1 spp for a first guess, then renders of about seconds / 4 and `seconds` (`seconds` is half
    the largest budget), each twice, the faster counted; up to two more aimed at `seconds` while
    the last one took under 0.7 or over 1.4 times it. The line through the last two, seconds = fixed + seconds_per_spp * spp,
    is the cost model: near the budgets, where it is used (a short render costs more per sample:
    a BDPT pass ends with a drain of its longest paths, mlt starts its chains)."""
    start = time.perf_counter()
    render_job(job, 1, job.seed)                 # also warms up, the first time in this process
    warmup = time.perf_counter() - start
    probes = [(1, render_job(job, 1, job.seed).stats["seconds"])]
    for share in (0.25, 1.0, 1.0, 1.0):
        if share == 1.0 and len(probes) > 2 and 0.7 <= probes[-1][1] / seconds <= 1.4:
            break      # the last probe landed near `seconds`: the line through the last two holds there
        # Else probe again: a first guess from 1 spp can be far off where a short render costs more
        # than its share (mlt's start = pool: the candidates' cost grows with the chains, which
        # grow with spp until every chain runs), and a line through such probes is too steep.
        fixed, per_spp = fit_cost(probes[-2:])
        floor = probes[-1][0] + 1 if len(probes) < 3 else 1
        spp = int(min(max(floor, (share * seconds - fixed) / per_spp), LIMITS["spp"][1]))
        # The faster of two: a busy moment of the machine only ever adds time.
        probes.append((spp, min(render_job(job, spp, job.seed).stats["seconds"] for _ in range(2))))
    fixed, per_spp = fit_cost(probes[-2:])
    pixels = job.run.resolution[0] * job.run.resolution[1]
    return {"warmup_seconds": warmup, "probes": [list(p) for p in probes], "fixed_seconds": fixed,
            "seconds_per_spp": per_spp, "samples_per_second": pixels / per_spp}


def fit_cost(probes):
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


def probe_seconds(budgets):
    """The calibration's longest probe: half the largest budget, within CALIBRATION_SECONDS."""
    return min(max(max(budgets) / 2, CALIBRATION_SECONDS[0]), CALIBRATION_SECONDS[1])
