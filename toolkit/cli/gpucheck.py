"""`python -m toolkit gpucheck`: the toolkit checked and measured on one device, one report."""
from toolkit.cli.options import DEVICE
from toolkit.verify import gpucheck


def add_command(sub):
    p = sub.add_parser("gpucheck", help="check and measure the toolkit on a device (a GPU if there is one): "
                                        "same-image tests, Embree cross-check, bench, compare; one report",
                       description="On the chosen device: the same-image checks, the Embree cross-check, bench of "
                                   "every technique (stream vs in-place ratios against the talk's) and compare with "
                                   "SIMD figures, GPU against CPU where both exist. Writes one report (text and "
                                   "JSON); exit code 1 when a correctness check fails.",
                       parents=[DEVICE])
    p.add_argument("--fast", action="store_true", help="tiny renders (what the test suite runs)")
    p.add_argument("--out", default="out/gpucheck.txt",
                   help="the report (text); its JSON goes beside it as .json (default out/gpucheck.txt)")
    p.set_defaults(run=cmd_gpucheck)


def cmd_gpucheck(args):
    out = gpucheck.report_path(args.out)      # before the run: a bad --out must not cost its time
    report = gpucheck.run(device=args.device, fast=args.fast, out_dir=str(out.parent / (out.stem + "_compare")))
    text, data = gpucheck.write_report(report, out)
    print(gpucheck.format_report(report))
    print(f"wrote {text} and {data}")
    return 0 if report["passed"] else 1
