"""The offline GPU build's report (toolkit/verify/offline_build.py): per kernel and target, the
most each kernel asks for over all its builds, as Markdown tables (printed, and what the
docs and results/ show), and the JSON with every build's figures."""
import json
from pathlib import Path

from toolkit.core.validate import InputError, writable_file
from toolkit.verify.gpu_occupancy import SM90

# The columns of each target's table: (heading, the kernel's field, "max" or "min" over its builds).
COLUMNS = {
    "nvptx64": [("registers", "registers", max), ("spill bytes", "spill_bytes", max),
                ("stack bytes", "stack_bytes", max), ("shared bytes", "shared_bytes", max),
                (f"warps/SM (of {SM90['max_warps']})", "warps_per_sm", min)],
    "amdgcn": [("VGPRs", "vgprs", max), ("SGPRs", "sgprs", max), ("spilled VGPRs", "vgpr_spills", max),
               ("spilled SGPRs", "sgpr_spills", max), ("scratch bytes", "scratch_bytes", max),
               ("LDS bytes", "lds_bytes", max), ("waves/SIMD (of 8)", "waves_per_simd", min)],
}
# What the figures of one build mean, under each table.
NOTES = {
    "nvptx64": "Per thread: registers, spill stores and the stack frame (private arrays such as the BVH stack, "
               "in local memory); per work-group of 64: shared (OpenCL local) memory. Warps per SM: what sm_90 "
               "can hold at once with these (toolkit/verify/gpu_occupancy.py), and what limits it.",
    "amdgcn": "Per work-item: vector and scalar registers, registers spilled (SGPRs spill into VGPR lanes first), "
              "scratch (private memory: the stack); per work-group: LDS (local memory). Waves per SIMD: the "
              "compiler's own occupancy figure.",
}


def json_path(value):
    """--json checked before any work: a .json name in a folder that accepts new files."""
    path = writable_file(value, "a JSON file", option="--json")
    if path.suffix.lower() != ".json":
        raise InputError(f"--json {path}: give a .json name")
    return path


def write_json(report, path):
    """The report at `path`, written whole beside it and then moved there."""
    path = Path(path)
    partial = path.with_name(f".{path.name}.partial")
    partial.write_text(json.dumps(report, indent=1) + "\n")
    partial.replace(path)
    return path


def per_kernel(report, target):
    """[(kernel, its rows)] of one target, in the order the kernels were first built."""
    kernels = {}
    for row in report["kernels"]:
        if row["target"] == target:
            kernels.setdefault(row["kernel"], []).append(row)
    return list(kernels.items())


def _cell(rows, field, most):
    values = [row[field] for row in rows if row.get(field) is not None]
    if not values:
        return "–"
    value = most(values)
    if field == "warps_per_sm":
        limits = sorted({row["occupancy_limited_by"] for row in rows if row[field] == value})
        return f"{value} ({', '.join(limits)})"
    return f"{value:,}"


def kernel_table(report, target):
    """One target's Markdown table: per kernel, its builds, how many built, and its figures."""
    columns = COLUMNS[target]
    if target == "nvptx64" and not any(row.get("assembled") for row in report["kernels"] if row["target"] == target):
        columns = []        # no ptxas here: PTX only, no figures
    head = ["kernel", "builds", "built", *(heading for heading, _, _ in columns)]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join(["---"] + ["---:"] * (len(head) - 1)) + "|"]
    for kernel, rows in per_kernel(report, target):
        built = sum(row["ok"] for row in rows)
        cells = [f"`{kernel}`", str(len(rows)), "all" if built == len(rows) else str(built),
                 *(_cell(rows, field, most) for _, field, most in columns)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def failures(report):
    """One line per build that failed: the kernel, target, program, the renders that use it, the error."""
    lines = []
    for row in report["kernels"]:
        if not row["ok"]:
            used_by = report["builds"][row["build"]]["uses"]
            uses = ", ".join(used_by[:3]) + (f" and {len(used_by) - 3} more" if len(used_by) > 3 else "")
            error = row["error"].replace("\n", "\n    ")
            lines.append(f"- FAILED `{row['kernel']}` for {row['target']} (cl/{row['program']}, used by {uses}):\n"
                         f"    {error}")
    return lines


def format_report(report):
    """The printed report, in Markdown: what was built with what, one table per target, failures."""
    targets = len(report["targets"])
    out = [f"{len(report['builds']) // targets} programs, each built for {targets} targets in "
           f"{report['seconds']:.0f} s, with {report['clang']} and libclc ({report['libclc']}); "
           + (f"PTX assembled by ptxas, {report['ptxas']}." if report["ptxas"] else
              "no ptxas found: the PTX is checked, not assembled (no registers; install a CUDA toolkit "
              "or `pip install nvidia-cuda-nvcc-cu12` for them).")]
    for target, label in report["targets"].items():
        rows = [row for row in report["kernels"] if row["target"] == target]
        built = sum(row["ok"] for row in rows)
        out += ["", f"**{label}**: {built} of {len(rows)} kernel builds succeeded. Per kernel, the most over "
                    "its builds (the fewest warps or waves):", "", kernel_table(report, target), "",
                NOTES[target]]
    problems = failures(report)
    out += ["", "Every kernel built for every target." if report["passed"] else
            f"{len(problems)} kernel builds failed:", *problems]
    return "\n".join(out)
