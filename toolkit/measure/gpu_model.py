"""A model of a technique's wall time on a GPU, from the host meter's figures measured on this CPU
(toolkit/measure/host_meter.py) and the kernel times a GPU recorded (gpucheck's JSON, time per phase).
Issue 48, item 5: what the host's habits cost a GPU before a GPU is at hand to measure it.

Per sample (or for one whole render, `predict_render`), the GPU's wall time is

    serial + max(kernels, host - serial) + drains x DRAIN_SECONDS + bytes moved / LINK_BYTES_PER_SECOND

Its assumptions, each a choice to check against a GPU's own measurement (test_gpu_model.py checks
the whole against the H200's):
1. The host does the same work on the GPU's machine as on this CPU (the same code, the same calls),
   and at the same speed, times `host_speed` (1: the GPU machine's CPU runs the Python of the host
   loop as fast as this 2-core Zen 4 does; its thread's CPU time is what the meter measured).
2. The host's CPU time overlaps the kernels except its serial part: from a drain (a blocking read or
   write, a finish, a wait on the last command queued) to its next launch the device has nothing
   to run (toolkit/opencl/traffic.py measures it). Between drains, the device runs what the host has
   queued while the host queues more, so that stretch takes the longer of the two. Where the meter's
   extra samples made no drain, their serial time is taken as none (what the meter shows there is
   the noise of the renders' fixed drains).
3. Each drain also costs a round trip the host's CPU time does not show: the device's completion
   reaching the host, then the next launch reaching the device (DRAIN_SECONDS, a discrete GPU's
   launch and completion latency over PCIe and its driver, ~10 us each way).
4. The bytes read back and written cross the host link at LINK_BYTES_PER_SECOND (PCIe 5 x16 as
   measured in practice), not overlapped with kernels (most reads are blocking today).
5. The kernels take on the GPU the time per sample it recorded for that technique (gpucheck's time
   per phase: SIMD counters on there, taken to cost the same off). A technique it did not time takes
   this CPU's kernel time scaled by a timed sibling's GPU/CPU ratio (SIBLINGS): pt_naive by
   pt_inplace_regen's, corrected by their SIMD efficiencies on the GPU (a GPU spends its time on
   whole warps, idle lanes included; this CPU's PoCL runs each work-item as a thread of its own);
   mlt by bdpt_parallel_connect's, whose kernels evaluate its proposals (no efficiency recorded
   for mlt on the GPU: no correction).
6. Fixed costs (buffers made, the first launch) are left out of the per-sample figures: the meter's
   figures are what its 3N more samples cost. (At the GPU's sizes a render's fixed cost on this CPU
   includes faulting in gigabytes of fresh pool memory, at a price that varies by seconds: the meter's
   method there, host_meter.py's Precision, keeps it from the difference.) The GPU's recorded kernel
   times are one render each, not a difference: BDPT's is one pool walked to its end, whose tail a
   steady state would spread over more samples (results/issue48_model_inputs.md estimates it).
"""
from toolkit.measure.phases import COUNTER_KERNELS, HOST

DRAIN_SECONDS = 20e-6
LINK_BYTES_PER_SECOND = 25e9
# A technique without recorded GPU kernel times: the timed technique its kernels are scaled from.
SIBLINGS = {"pt_naive": "pt_inplace_regen", "mlt": "bdpt_parallel_connect"}
# The talk's two ratios, in wall time: (faster technique, slower technique, the talk's GPU figure).
TALK_RATIOS = {"compaction + regeneration over in-place regeneration": ("pt_compact_regen", "pt_inplace_regen", 1.2),
               "parallel over naive connect": ("bdpt_parallel_connect", "bdpt_naive_connect", 1.15)}


def gpu_kernel_ns(gpucheck):
    """{technique: kernel ns per sample} that a gpucheck report's time per phase recorded."""
    found = {}
    for technique, phase in gpucheck.get("phases", {}).items():
        samples = phase["samples_per_second"] * phase["seconds"]
        found[technique] = sum(row["ms"] for row in phase["rows"]     # the technique's own kernels: no counters
                               if row["kernel"] not in (HOST, *COUNTER_KERNELS)) * 1e6 / samples
    return found


def gpu_efficiency(gpucheck, technique):
    """The overall SIMD efficiency the GPU's compare measured for `technique`, or None."""
    return gpucheck.get("compare", {}).get(technique, {}).get("simd_efficiency", {}).get("overall")


def kernel_ns_on_gpu(technique, gpucheck, cpu_kernel_ns):
    """(kernel ns per sample on the GPU, where it comes from). `cpu_kernel_ns`: {technique: this CPU's
    kernel ns per sample}, for the techniques the GPU did not time (assumption 5)."""
    recorded = gpu_kernel_ns(gpucheck)
    if technique in recorded:
        return recorded[technique], "recorded on the GPU"
    sibling = SIBLINGS.get(technique)
    if sibling not in recorded or technique not in cpu_kernel_ns or sibling not in cpu_kernel_ns:
        raise ValueError(f"no kernel time for {technique} on the GPU, and none to scale it from")
    scale = recorded[sibling] / cpu_kernel_ns[sibling]
    mine, theirs = gpu_efficiency(gpucheck, technique), gpu_efficiency(gpucheck, sibling)
    lanes = theirs / mine if mine and theirs else 1.0
    why = f"this CPU's, scaled by {sibling}'s GPU/CPU ratio" + (f" and SIMD efficiencies ({theirs:.0%}/{mine:.0%})"
                                                               if lanes != 1.0 else "")
    return cpu_kernel_ns[technique] * scale * lanes, why


def model_wall(kernel, host, serial, drains, moved_bytes, unit=1.0):
    """The module's formula: wall time from kernel, host and serial time (in seconds x `unit`: 1 for
    seconds, 1e9 for ns), the drains and the bytes moved; the result in the same unit."""
    return (serial + max(kernel, host - serial) + drains * DRAIN_SECONDS * unit
            + moved_bytes / LINK_BYTES_PER_SECOND * unit)


def predict_render(figures, kernel_seconds, host_speed=1.0):
    """One render's wall seconds on the GPU: `figures`, the meter's counts of that render on this CPU
    (traffic.Traffic.figures()); `kernel_seconds`, its kernels' time on the GPU."""
    return model_wall(kernel_seconds, figures["cpu_seconds"] * host_speed, figures["serial_seconds"] * host_speed,
                      figures["drains"], figures["read_bytes"] + figures["write_bytes"])


def predict(meter, gpucheck, cpu_meter=None, host_speed=1.0):
    """Per technique of the meter's report (`meter`: host_meter's, best at the GPU's sizes), what a
    sample costs on the GPU of `gpucheck` (ns: kernels, host, serial, round trips, transfers, wall)
    and its samples/s; against this CPU's samples/s (the wall time per sample of `cpu_meter`, the
    meter at the CPU's own sizes, or else of `meter`); and the talk's two ratios in wall time."""
    rows = meter["techniques"]
    cpu_rows = (cpu_meter or meter)["techniques"]
    cpu_kernel = {name: row["kernel_ns_per_sample"] for name, row in rows.items()}
    out = {}
    for name, row in rows.items():
        kernel, source = kernel_ns_on_gpu(name, gpucheck, cpu_kernel)
        host, drains = row["host_cpu_ns_per_sample"] * host_speed, row["drains_per_million"] * 1e-6
        # Serial time follows a drain: where the extra samples made none, the figure is the difference
        # of the two renders' fixed drains (their start and end), noise of either sign (pt_inplace_regen:
        # -1.2 to 2.0 ns over 7 pairs, 2026-12-06), and none is counted.
        serial = max(row["serial_ns_per_sample"], 0.0) * host_speed if drains > 0 else 0.0
        moved = row["read_bytes_per_sample"] + row["write_bytes_per_sample"]
        total = model_wall(kernel, host, serial, drains, moved, unit=1e9)
        cpu_rate = 1e9 / cpu_rows[name]["wall_ns_per_sample"] if name in cpu_rows else None
        out[name] = {"kernel_ns": kernel, "kernel_source": source, "host_ns": host, "serial_ns": serial,
                     "round_trip_ns": drains * DRAIN_SECONDS * 1e9,
                     "link_ns": moved / LINK_BYTES_PER_SECOND * 1e9, "wall_ns": total, "kernel_share": kernel / total,
                     "samples_per_second": 1e9 / total, "cpu_samples_per_second": cpu_rate,
                     "gpu_over_cpu": 1e9 / total / cpu_rate if cpu_rate else None}
    ratios = {label: {"of": f"{a} / {b}", "talk": talk,
                      "wall": out[b]["wall_ns"] / out[a]["wall_ns"], "kernels": out[b]["kernel_ns"] / out[a]["kernel_ns"]}
              for label, (a, b, talk) in TALK_RATIOS.items() if a in out and b in out}
    return {"gpu": gpucheck["device"]["name"], "cpu": (cpu_meter or meter).get("device"), "host_speed": host_speed,
            "meter": {"resolution": meter["resolution"], "gpu_sizes": meter["gpu_sizes"]},
            "techniques": out, "ratios": ratios}


def what_holds_it(row):
    """The largest part of a predicted sample's time, in words."""
    parts = {"kernels": row["kernel_ns"] if row["kernel_ns"] >= row["host_ns"] - row["serial_ns"] else 0.0,
             "host (overlapped)": max(row["host_ns"] - row["serial_ns"] - row["kernel_ns"], 0.0),
             "host while the GPU waits": row["serial_ns"], "round trips": row["round_trip_ns"],
             "transfers": row["link_ns"]}
    return max(parts, key=parts.get)


def format_prediction(prediction):
    """The prediction as Markdown tables (the docs' GPU page shows them)."""
    lines = ["| technique | kernels (ns/sample) | host CPU | of it serial | round trips | transfers | wall | "
             "kernels' share | GPU samples/s | over this CPU | held by |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for name, r in prediction["techniques"].items():
        over = f"{r['gpu_over_cpu']:,.0f}x" if r["gpu_over_cpu"] else "-"
        lines.append(f"| {name} | {r['kernel_ns']:,.1f} | {r['host_ns']:,.1f} | {r['serial_ns']:,.1f} | "
                     f"{r['round_trip_ns']:,.1f} | {r['link_ns']:,.1f} | {r['wall_ns']:,.1f} | {r['kernel_share']:.0%} | "
                     f"{r['samples_per_second'] / 1e6:,.2f} M | {over} | {what_holds_it(r)} |")
    lines += ["", "| the talk's ratio | predicted, wall time | kernels only | talk |", "|---|---:|---:|---:|"]
    for label, r in prediction["ratios"].items():
        lines.append(f"| {label} ({r['of']}) | {r['wall']:.2f}x | {r['kernels']:.2f}x | {r['talk']:.2f}x |")
    return "\n".join(lines)


def against_measured(renders, gpucheck, host_speed=1.0):
    """The model's validation: {technique: predicted and measured wall seconds of one render, and their
    ratio}. `renders`: {technique: the meter's figures of one render on this CPU, with its samples and
    kernel seconds} of the code the GPU ran, at the settings of the GPU's bench (gpucheck's "bench":
    one render of the same samples; its samples/s gives the measured wall time)."""
    cpu_kernel = {name: r["kernel_seconds"] / r["samples"] * 1e9 for name, r in renders.items()}
    measured_rates = {name: row["samples_per_second"] for name, row in gpucheck["bench"]["techniques"].items()}
    out = {}
    for name, r in renders.items():
        if name not in measured_rates:
            continue
        kernel_ns, source = kernel_ns_on_gpu(name, gpucheck, cpu_kernel)
        predicted = predict_render(r, kernel_ns * 1e-9 * r["samples"], host_speed)
        measured = r["samples"] / measured_rates[name]
        out[name] = {"predicted_seconds": predicted, "measured_seconds": measured, "ratio": predicted / measured,
                     "kernel_source": source}
    return out


def format_validation(checked):
    """against_measured's figures as a Markdown table."""
    lines = ["| technique | predicted wall (ms) | measured on the GPU (ms) | predicted / measured | kernels from |",
             "|---|---:|---:|---:|---|"]
    for name, r in checked.items():
        lines.append(f"| {name} | {r['predicted_seconds'] * 1e3:,.1f} | {r['measured_seconds'] * 1e3:,.1f} | "
                     f"{r['ratio']:.2f} | {r['kernel_source']} |")
    return "\n".join(lines)
