"""`python -m toolkit study`: the speed-accuracy study (toolkit/measure/study/), error against
time for each technique or each value of an accuracy knob."""
import json

from toolkit.cli.options import (BVH, DEVICE, SCENE, TECHNIQUE_NAMES, number, numbers, positive, resolution,
                                 technique_list, whole)
from toolkit.measure.study import (DEFAULT_BUDGETS, DEFAULT_REPEATS, DEFAULT_TARGET, DEFAULT_TECHNIQUES,
                                   format_study, study)

DESCRIPTION = (
    "Error against time for each technique, or for each value of an accuracy knob, against the "
    "scene's reference: MSE split into bias^2 and variance over independent repetitions, "
    "efficiency 1/(MSE x time), the log-log slope of RMSE against time, the time to a relative "
    "RMSE target, the same over the 10% hardest pixels, each with its standard error. Time budgets "
    "are turned into sample counts by a short calibration of each run (the plan is in the JSON), "
    "and each repetition has its own seed, so a study is reproducible. Prints a table; writes "
    "study.json and plots to --out.")


def add_command(sub):
    p = sub.add_parser(
        "study", help="the speed-accuracy study: error (bias^2, variance) against time per technique or knob value",
        description=DESCRIPTION, parents=[DEVICE, SCENE, BVH])
    p.add_argument("--techniques", default=",".join(DEFAULT_TECHNIQUES),
                   help=f"comma-separated, from: {TECHNIQUE_NAMES} (default {','.join(DEFAULT_TECHNIQUES)})")
    p.add_argument("--budgets", default=",".join(f"{b:g}" for b in DEFAULT_BUDGETS), metavar="SECONDS,...",
                   help="seconds of rendering per repetition (default %(default)s); each becomes a sample count "
                        "per run by calibration (build and warm-up excluded and reported apart), so runs are "
                        "reproducible")
    p.add_argument("--spp-budgets", metavar="SPP,...",
                   help="instead of --budgets: fixed samples per pixel for every run, no calibration (to "
                        "reproduce a study's plan, or for tests)")
    p.add_argument("--repeats", type=positive, default=DEFAULT_REPEATS,
                   help="independent repetitions per budget, each with its own seed (default %(default)s; "
                        "at least 2 to split bias^2 from variance, 3 for standard errors)")
    p.add_argument("--resolution", type=resolution, default=(32, 32),
                   help="WxH (default 32x32, which every bundled reference averages to)")
    p.add_argument("--seed", type=whole, default=0,
                   help="base seed: repetition r of budget k uses seed + k x repeats + r")
    p.add_argument("--knob", metavar="NAME=V1,V2,...",
                   help="sweep an accuracy knob for each technique: max_depth, rr_depth, clamp (scene integrator "
                        "settings; clamp=none,10), pass_spp, resolution (8x8,16x16), or a technique option such "
                        "as mlt's chains, start, large_step")
    p.add_argument("--target", type=number, default=DEFAULT_TARGET,
                   help="relative RMSE target for the time-to-target figures (default %(default)s: 5%% of the "
                        "reference's mean)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the repetitions on an existing Dask cluster (tcp://host:8786); each worker uses its "
                        "own OpenCL device; needs pip install \".[cluster]\"")
    p.add_argument("--out", default="out/study", help="folder for study.json and the plots (default out/study)")
    p.add_argument("--json", action="store_true", help="print the report as JSON as the last line of stdout")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (calibration, then the renders)")
    p.add_argument("--specialization", action="store_true",
                   help="also measure the kernels specialized to the scene against the general kernel (every "
                        "material and feature compiled in) for the study's techniques: samples/s ratio, uncached "
                        "build time, binary size (bench --specialization does every bundled scene)")
    p.set_defaults(run=cmd_study)


def cmd_study(args):
    spp_budgets = numbers(args.spp_budgets, int, "--spp-budgets") if args.spp_budgets else None
    budgets = numbers(args.budgets, float, "--budgets")
    report = study(args.scene, technique_list(args.techniques), budgets=budgets, repeats=args.repeats,
                   resolution=args.resolution, seed=args.seed, spp_budgets=spp_budgets, knob=args.knob,
                   target=args.target, scheduler=args.scheduler, device=args.device, bvh=args.bvh,
                   out_dir=args.out, progress=not args.no_progress, specialization=args.specialization)
    print(format_study(report))
    print(f"report: {args.out}/study.json")
    if args.json:
        print(json.dumps(report, default=str))
    return 0
