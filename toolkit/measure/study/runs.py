"""study(): the speed-accuracy study from its inputs to its report, in named steps: check the
inputs, plan the sample counts (a calibration, or the given counts), render the repetitions, and
gather their figures (the package docstring says what each figure means)."""
import time

from toolkit.api import as_scene
from toolkit.core.scene import Scene
from toolkit.core.validate import InputError, finite_number, whole_number, writable_folder
from toolkit.measure.specialization import measure_specialization
from toolkit.measure.study.calibration import calibrate, plan, probe_seconds
from toolkit.measure.study.knobs import DEFAULT_RESOLUTION, Repetition, check_run, make_runs, parse_knob
from toolkit.measure.study.plots import save_plots
from toolkit.measure.study.report import report_head, run_report, write_report
from toolkit.measure.study.workers import map_jobs, run_repetition, scene_digest

DEFAULT_TECHNIQUES = ("pt_naive", "pt_compact_regen", "bdpt_parallel_connect", "mlt")
DEFAULT_BUDGETS = (0.1, 0.2, 0.4, 0.8, 1.6)     # seconds per repetition: the default run takes ~1 minute
DEFAULT_REPEATS = 3
DEFAULT_TARGET = 0.05


def study(scene=None, techniques=DEFAULT_TECHNIQUES, budgets=DEFAULT_BUDGETS, repeats=DEFAULT_REPEATS,
          resolution=DEFAULT_RESOLUTION, seed=0, spp_budgets=None, knob=None, target=DEFAULT_TARGET,
          scheduler=None, device=None, bvh="wide", out_dir=None, progress=False, specialization=False):
    """Error against time for each technique (and knob value) on `scene`; returns the report
    (a dict that json.dumps writes) and, with `out_dir`, writes study.json and the plots there.

    `budgets` are seconds of rendering per repetition; each is turned into a sample count by a
    calibration of each run (see the package docstring), so the renders, and with the same plan
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
    # Where the results go, checked before the study runs (a folder found unwritable at the end
    # lost every result), as every other input is.
    out_dir = None if out_dir is None else writable_folder(out_dir)
    given = scene
    scene = as_scene(scene)
    # What a worker gets: the scene file's absolute path with the digest of what was loaded here
    # (workers.py), or a Scene made in Python itself (pickled).
    if isinstance(given, Scene):
        shipped, digest = given, None
    else:
        shipped, digest = str(scene.path.resolve()), scene_digest(scene)
    repeats = whole_number("study.repeats", repeats, "repeats")
    seed = whole_number("seed", seed)
    target = finite_number("study.target", target, "target")
    knob = parse_knob(knob) if isinstance(knob, str) else knob
    runs = _checked_runs(scene, techniques, knob, resolution)
    budget_list, unit, plans = _budgets(budgets, spp_budgets, [r.label for r in runs])
    whole_number("seed", seed + len(budget_list) * repeats - 1, "seed + budgets x repeats - 1 (the last seed)")

    def job(run, spp, s):
        return Repetition(shipped, run, spp, s, device, bvh, digest)

    calibration = {}
    if unit == "seconds":
        calibration = _calibrate(runs, budget_list, seed, job, scheduler, progress)
        plans = {label: plan(calibration[label], budget_list) for label in calibration}
    renders, device_name = _render_repetitions(runs, plans, len(budget_list), repeats, seed, job, scheduler, progress)
    report = report_head(scene, resolution, device_name, unit, budget_list, repeats, seed, target, scheduler, knob)
    for run in runs:
        report["runs"][run.label] = run_report(scene, run, renders, plans[run.label], calibration.get(run.label),
                                               budget_list, repeats, seed, target)
    if specialization:   # on this machine, not on the cluster: a ratio of two local measurements
        names = list(dict.fromkeys(run.technique for run in runs))
        report["specialization"] = measure_specialization(scene, names, resolution=tuple(resolution),
                                                          device=device, bvh=bvh)
    report["study_seconds"] = time.perf_counter() - started
    if out_dir is not None:
        report["plots"] = save_plots(report, renders, scene, out_dir)
        write_report(report, out_dir / "study.json")
    return report


def _checked_runs(scene, techniques, knob, resolution):
    """The study's runs, each checked before any work (settings within limits, a reference)."""
    if isinstance(techniques, str):
        techniques = [t.strip() for t in techniques.split(",") if t.strip()]
    if not techniques:
        raise InputError("no technique given")
    runs = make_runs(techniques, knob, resolution)
    labels = [r.label for r in runs]
    if len(set(labels)) != len(labels):
        raise InputError(f"a run is given twice: {', '.join(labels)}")
    for run in runs:
        check_run(scene, run)
    return runs


def _budgets(budgets, spp_budgets, labels):
    """(budget list, unit, plans): time budgets in seconds (plans None: the calibration makes them),
    or with `spp_budgets` the given sample counts of every run."""
    if spp_budgets is None:
        budget_list = [finite_number("study.budget", float(b), "budget") for b in budgets]
        if not budget_list:
            raise InputError("no budget given")
        return budget_list, "seconds", None
    per_run = spp_budgets if isinstance(spp_budgets, dict) else {label: spp_budgets for label in labels}
    plans = {}
    for label in labels:
        if label not in per_run:
            raise InputError(f"spp_budgets has no sample counts for {label!r}")
        plans[label] = [whole_number("spp", s, "spp budget") for s in per_run[label]]
    count = len(next(iter(plans.values())))
    if any(len(p) != count for p in plans.values()):
        raise InputError("spp_budgets: every run needs the same number of budgets")
    return list(next(iter(plans.values()))), "spp", plans


def _calibrate(runs, budget_list, seed, job, scheduler, progress):
    """{label: calibration} of every run, its probes aimed at half the largest budget."""
    cal_seed = (seed + (1 << 31)) % (1 << 32)       # apart from the study's seeds
    probe = probe_seconds(budget_list)
    results = map_jobs(calibrate, [(job(run, 1, cal_seed), probe) for run in runs], scheduler, progress,
                       "calibration")
    return {run.label: result for run, result in zip(runs, results)}


def _render_repetitions(runs, plans, budgets, repeats, seed, job, scheduler, progress):
    """Every repetition of every run at every budget: ({(label, k): {"images", "stderrs", "dofs",
    "seconds"}}, the device's name). Repetition r of budget k has the seed seed + k * repeats + r."""
    # Interleaved (repetition, budget, run): a slow moment of the machine does not favour one run.
    items = [(r, k, run) for r in range(repeats) for k in range(budgets) for run in runs]
    results = map_jobs(run_repetition, [(job(run, plans[run.label][k], seed + k * repeats + r),)
                                        for r, k, run in items], scheduler, progress, "study")
    renders, device_name = {}, None
    for (r, k, run), res in zip(items, results):
        got = renders.setdefault((run.label, k), {"images": [], "stderrs": [], "dofs": [], "seconds": []})
        for key, value in (("images", "image"), ("stderrs", "stderr"), ("dofs", "dof"), ("seconds", "seconds")):
            got[key].append(res[value])
        device_name = res["device"]
    return renders, device_name
