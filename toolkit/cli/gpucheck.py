"""`python -m toolkit gpucheck`: the toolkit checked and measured on one device, one report."""
from pathlib import Path

from toolkit.cli.options import DEVICE
from toolkit.verify import cpu_references, gpucheck


def add_command(sub):
    p = sub.add_parser("gpucheck", help="check and measure the toolkit on a device (a GPU if there is one): "
                                        "same-image tests, Embree cross-check, bench, compare; one report",
                       description="On the chosen device: the same-image checks (also against CPU reference "
                                   "images carried from another machine), the Embree cross-check, bench of "
                                   "every technique (stream vs in-place ratios against the talk's), compare with "
                                   "SIMD figures, GPU against CPU where both exist, time per phase and, without "
                                   "--fast, samples/s against the stream and pool sizes. Writes one report (text "
                                   "and JSON), after every step; exit code 1 when a correctness check fails.",
                       parents=[DEVICE])
    p.add_argument("--fast", action="store_true", help="tiny renders (what the test suite runs)")
    p.add_argument("--out", default="out/gpucheck.txt",
                   help="the report (text); its JSON goes beside it as .json (default out/gpucheck.txt)")
    p.add_argument("--cpu-references", metavar="DIR",
                   help="CPU images to compare this device's with (made by --write-cpu-references on a "
                        f"machine with a CPU runtime; default: {cpu_references.DEFAULT_FOLDER} where it exists)")
    p.add_argument("--write-cpu-references", metavar="DIR",
                   help="render the CPU reference images on --device (a CPU) into DIR, then stop")
    p.set_defaults(run=cmd_gpucheck)


def cmd_gpucheck(args):
    if args.write_cpu_references:
        manifest = cpu_references.write(args.write_cpu_references, device=args.device,
                                        log=lambda text: print(f"gpucheck: {text}", flush=True))
        print(f"wrote {len(manifest['entries'])} CPU reference images ({manifest['implementation']}) "
              f"to {args.write_cpu_references}")
        return 0
    out = gpucheck.report_path(args.out)      # before the run: a bad --out must not cost its time
    folder = args.cpu_references
    if folder is None and Path(cpu_references.DEFAULT_FOLDER, cpu_references.MANIFEST).is_file():
        folder = cpu_references.DEFAULT_FOLDER
    if folder is not None:
        cpu_references.load(folder)           # checked before the run, as --out is
    report = gpucheck.run(device=args.device, fast=args.fast, out_dir=str(out.parent / (out.stem + "_compare")),
                          cpu_reference_folder=folder, save=lambda partial: gpucheck.write_report(partial, out))
    text, data = gpucheck.write_report(report, out)
    print(gpucheck.format_report(report))
    print(f"wrote {text} and {data}")
    return 0 if report["passed"] else 1
