"""Time per phase next to SIMD efficiency, and the talk's model of what the time should be.

A phase is a kernel: each launch's device time comes from OpenCL's profiling events
(toolkit.render(..., time_phases=True), toolkit/opencl/kernel_times.py), its lane efficiency from
the SIMD counters the techniques already keep (toolkit/core/simd.py). Both come from the same
render, so they describe the same work.

The talk's model: a warp of W lanes issues every step that any of its lanes takes, so

    time  ~  work / (W x efficiency)  =  issued lane-steps / W,

with work = the active lane-steps. Normalised to a reference technique of the same family, W
cancels: predicted time ratio = issued lane-steps / the reference's. The model counts every
lane-step as the same cost; where the measured ratio differs, a phase costs what the counters
do not see (a lane waiting inside the BVH loop, the compaction's own scans, a launch's overhead),
or a device runs idle lanes cheaply (a CPU without lanes).
"""
# kernel -> (stage, the SIMD counters it runs, the traversal counters it runs). The counters are
# those of toolkit/core/simd.py's PhaseCounter, as each technique's count_* hooks name them.
KERNEL_PHASES = {
    "pt_naive_render": ("generate + extend + shade", ("generate", "extend", "shadow"), ("closest", "shadow")),
    "pt_inplace_regen_regenerate": ("regenerate", ("generate",), ()),   # the assignment's checks
    "pt_inplace_regen_trace": ("regenerate + extend: trace", ("generate", "extend"), ("closest",)),
    "pt_inplace_regen_shade": ("extend: shade", ("extend", "shadow"), ("shadow",)),
    "extend_in_place_trace": ("extend: trace", ("extend",), ("closest",)),
    "extend_in_place_shade": ("extend: shade", ("extend", "shadow"), ("shadow",)),
    "pt_compact_regen_generate": ("regenerate", ("generate",), ()),   # multi-pass compaction
    "pt_compact_regen_trace": ("shadow rays + regenerate + extend: trace", ("shadow", "generate", "extend"),
                               ("shadow", "closest")),   # the last step's queued shadow rays first
    "pt_compact_regen_shade": ("extend: shade + compact", ("extend", "compact"), ()),
    "pt_compact_regen_gather": ("compact (gather)", ("compact",), ()),
    "bdpt_regenerate": ("regenerate", ("generate",), ()),
    "bdpt_extend": ("walk + compact", ("walk", "compact"), ("closest",)),
    "bdpt_mark_terminated": ("find terminated", (), ()),
    "bdpt_list_offsets": ("scan", (), ()),              # the listed records' scan and the list of their slots
    "bdpt_list_terminated": ("scan", (), ()),
    "bdpt_naive_connect_splats": ("connect: count records", (), ()),
    "bdpt_parallel_connect_count": ("connect: count records", (), ()),
    "bdpt_naive_connect": ("connect", ("connect",), ()),
    "bdpt_parallel_connect": ("connect", ("connect",), ()),
    "compact_immediate": ("compact (list)", (), ()),
    "scan_blocks": ("scan", (), ()),
    "scan_add_block_offsets": ("scan", (), ()),
    "compact_scatter": ("compact (scatter)", (), ()),
    "film_reduce": ("film: sum per pixel", (), ()),
    "film_accumulate": ("film: add the pass", (), ()),
    "film_accumulate_pass": ("film: add the pass", (), ()),
    "record_film_add": ("film: add records", (), ()),
    "record_film_resolve": ("film: sum per pixel", (), ()),
    # the SIMD counters' own work (toolkit/opencl/simd_counters.py): a counted render's cost of measuring
    "simd_count_lanes": ("SIMD counters: sum a step's lanes", (), ()),
    "simd_count_packed": ("SIMD counters: sum a step's lanes", (), ()),
    "simd_count_two_steps": ("SIMD counters: sum a step's lanes", (), ()),
    "simd_count_turns": ("SIMD counters: sum a step's lanes", (), ()),
}
HOST = "(host, transfers)"   # the render's wall time that no kernel accounts for
# The SIMD counters' own kernels (toolkit/opencl/simd_counters.py): a counted render's cost of
# measuring, which a render without the counters does not pay.
COUNTER_KERNELS = ("simd_count_lanes", "simd_count_packed", "simd_count_two_steps", "simd_count_turns")


def phase_rows(stats):
    """One row per kernel the render launched, then the host's remainder: kernel, stage, launches,
    ms, share of the wall time, path-level and traversal lane efficiency (None: not counted)."""
    wall = stats["seconds"]
    rows = []
    for kernel, t in stats["kernel_times"].items():
        stage, simd, traversal = KERNEL_PHASES.get(kernel, (kernel, (), ()))
        rows.append({"kernel": kernel, "stage": stage, "launches": t["launches"], "ms": 1e3 * t["seconds"],
                     "share": t["seconds"] / wall if wall > 0 else float("nan"),
                     "simd_efficiency": _efficiency(stats["simd_lane_steps"], simd),
                     "traversal_efficiency": _efficiency(stats["traversal_lane_steps"], traversal)})
    rest = wall - sum(t["seconds"] for t in stats["kernel_times"].values())
    rows.append({"kernel": HOST, "stage": "between kernels", "launches": 0, "ms": 1e3 * rest,
                 "share": rest / wall if wall > 0 else float("nan"),
                 "simd_efficiency": None, "traversal_efficiency": None})
    return rows


def _efficiency(lane_steps, counters):
    """Active / issued lane-steps over the counters a kernel runs; None if it runs none."""
    active = sum(lane_steps[c][0] for c in counters if c in lane_steps)
    issued = sum(lane_steps[c][1] for c in counters if c in lane_steps)
    return active / issued if issued else None


def model_rows(table):
    """Per technique: the talk's predicted time ratio beside the measured ones, each family
    normalised to its first technique in `table` (compare's rows, with family, lane-steps and
    kernel times). `predicted` counts the path-level lane-steps, `predicted_traversal` the BVH
    loop's (each lane waits for its warp's longest traversal; BDPT counts only its walk's rays, not
    the connections' shadow rays, so there it sees the walk alone)."""
    out, reference = {}, {}
    for name, row in table.items():
        figures = {"issued": _issued(row["simd_lane_steps"]), "issued_traversal": _issued(row["traversal_lane_steps"]),
                   "kernel_seconds": sum(t["seconds"] for t in row["kernel_times"].values()),
                   "seconds": row["seconds"]}
        ref = reference.setdefault(row["family"], (name, figures))
        out[name] = {"family": row["family"], "reference": ref[0],
                     "predicted": _ratio(figures["issued"], ref[1]["issued"]),
                     "predicted_traversal": _ratio(figures["issued_traversal"], ref[1]["issued_traversal"]),
                     "measured_kernels": _ratio(figures["kernel_seconds"], ref[1]["kernel_seconds"]),
                     "measured_wall": _ratio(figures["seconds"], ref[1]["seconds"])}
    return out


def _issued(lane_steps):
    return sum(issued for _, issued in lane_steps.values())


def _ratio(a, b):
    return a / b if b else float("nan")


def _percent(x):
    return f"{x:>8.1%}" if x is not None else f"{'-':>8}"


def name_width(table, least):
    """The width of a column of technique names: the longest name and two spaces, at least `least`
    (a variant's name, "bdpt_parallel_connect/direct_scatter", is longer than the usual column)."""
    return max([least] + [len(name) + 2 for name in table])


def format_phases(table):
    """The per-phase tables and the model's ratios, as text."""
    w = name_width(table, 24)
    lines = ["Time per phase (device time of each kernel, OpenCL profiling events) and its lane efficiency, "
             "one run;", f"{HOST}: the wall time no kernel accounts for (Python, copies, reads);",
             "lanes: the path-level counters the kernel runs; BVH trav: its closest-hit and shadow rays' traversal.",
             f"{'technique':<{w}}{'phase (kernel)':<30}{'stage':<27}{'launches':>9}{'ms':>10}{'share':>8}"
             f"{'lanes':>8}{'BVH trav':>9}"]
    lines.append("-" * len(lines[-1]))
    for name, row in table.items():
        for r in row["phases"]:
            lines.append(f"{name:<{w}}{r['kernel']:<30}{r['stage']:<27}{r['launches']:>9}{r['ms']:>10.1f}"
                         f"{r['share']:>8.1%}{_percent(r['simd_efficiency'])}{_percent(r['traversal_efficiency'])}")
    lines += ["", "The talk's model: time ~ work / (W x efficiency) = issued lane-steps / W, as a ratio to the "
              "family's first technique (time, lower is faster):",
              f"{'technique':<{w}}{'reference':<{w}}{'model':>8}{'model+BVH':>11}{'kernels':>9}{'wall':>8}"]
    for name, m in model_rows(table).items():
        lines.append(f"{name:<{w}}{m['reference']:<{w}}{m['predicted']:>8.2f}{m['predicted_traversal']:>11.2f}"
                     f"{m['measured_kernels']:>9.2f}{m['measured_wall']:>8.2f}")
    return "\n".join(lines)
