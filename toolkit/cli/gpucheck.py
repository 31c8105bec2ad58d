"""`python -m toolkit gpucheck`: the toolkit checked and measured on one device, one report."""
from pathlib import Path

import toolkit.cli.gpucheck_run as gpucheck   # its run and report (a module, so a test can replace its run)
from toolkit.cli.options import DEVICE
from toolkit.core.validate import InputError
from toolkit.verify import cpu_references, offline_build, offline_report


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
    offline = p.add_argument_group("offline GPU build (no OpenCL device needed)")
    offline.add_argument("--offline", action="store_true",
                         help="build every kernel of every technique and variant, as the host would on a GPU, for "
                              "NVIDIA sm_90 (clang, then ptxas where found) and AMD gfx90a with clang and libclc "
                              "(apt-get install clang-16 libclc-16); print registers, spills, stack, shared memory "
                              "and occupancy per kernel; exit code 1 when a kernel does not build")
    offline.add_argument("--json", metavar="FILE", help="with --offline: also write every build's figures to FILE")
    p.set_defaults(run=cmd_gpucheck)


# The options of a run on a device, which --offline (no device) does not take.
_DEVICE_RUN_OPTIONS = {"device": "--device", "fast": "--fast", "cpu_references": "--cpu-references",
                       "write_cpu_references": "--write-cpu-references"}


def cmd_offline(args):
    given = [option for name, option in _DEVICE_RUN_OPTIONS.items() if getattr(args, name, None)]
    if given:
        raise InputError(f"--offline builds the kernels without a device; {' and '.join(given)} "
                         f"{'belongs' if len(given) == 1 else 'belong'} to a run on a device")
    json_file = offline_report.json_path(args.json) if args.json else None   # before the builds
    tools = offline_build.find_toolchain()
    report = offline_build.run(tools=tools, log=lambda text: print(f"gpucheck --offline: {text}", flush=True))
    report["command"] = "python -m toolkit gpucheck --offline" + (f" --json {args.json}" if args.json else "")
    print(offline_report.format_report(report))
    if json_file:
        print(f"wrote {offline_report.write_json(report, json_file)}")
    return 0 if report["passed"] else 1


def cmd_gpucheck(args):
    if args.offline:
        return cmd_offline(args)
    if args.json:
        raise InputError("--json goes with --offline; a run on a device writes its JSON beside --out")
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
