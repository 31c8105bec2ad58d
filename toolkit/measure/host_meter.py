"""The host meter (`python -m toolkit bench --host`): what rendering costs the host, per sample,
on any device, so that a CPU can tell what will hold a GPU back.

Each technique renders twice, at N and at 4N samples per pixel (path tracers 16 and 64 by default,
BDPT and Metropolis a quarter of that, but 16 and 64 at the GPU's sizes), and the meter reports what
the 3N more samples cost: the fixed costs of a render (buffers made, kernels found built, the scene's
upload) drop out.
Per sample: the CPU time of the thread that drives the queue (time.thread_time) outside the calls
that wait for the device (kept apart as `wait_cpu_ns_per_sample`: where the waiting thread runs the
kernels itself, Intel's CPU runtime, it is the kernels' time, not the host's; PoCL's waits sleep),
the part of it during which the device's queue was empty (`serial`: toolkit/opencl/traffic.py), the bytes read
back and written, the kernels' device time (OpenCL's profiling events). Per million samples: the
reads, the blocking transfers and the launches. Per pass, from the 4N render: blocking transfers
and launches. And the kernels' share of the 4N render's wall time.

Counts come from toolkit/opencl/traffic.py (pyopencl's entry points, wrapped while a render is
measured); the kernel times from toolkit/opencl/kernel_times.py (`time_phases`). SIMD counters are
off, unless `count_simd=True` (`bench --host --count-simd`): what a counted render (compare's, gpucheck's
phases, the demo's) costs the host, the counters summed on the device (toolkit/opencl/simd_counters.py)
and read once. `gpu_sizes=True` renders at a GPU's sizes (GPU_SIZES: the H200's streams and pools and
Metropolis's chain cap), so that a CPU measures the host's work of a GPU's render.

Precision. The difference of two renders is exact for the counts and noisy for the times: a
render's fixed cost (its start, the buffers it frees) varies by tens of milliseconds on a loaded
machine, and at the GPU's sizes by seconds. There every render makes its technique's memory anew
(api.render), BDPT's pool and Metropolis's chains: about 2.3 GB of vertex memory at a pool of
270,336, which PoCL takes from the operating system and which the kernels that first write it
(bdpt_regenerate) fault in, page by page: ~580,000 minor page faults in every such render, the N
one and the 4N one alike, so that they cancel in the difference, but at a cost that varied from
0.6 s to 9.7 s of bdpt_regenerate's kernel time (1.1 to 4.8 s of the process's system time) from
render to render on this shared machine (results/issue48_model_inputs.md). A GPU pays none of it.
Three things keep the 3N more samples well above that noise:
- N = spp at the GPU's sizes for every technique (`n_rule`): BDPT's quarter of 16 spp was one pool
  of 262,144 samples, ~1.5 s of kernel work beside a first touch that could take 3 s more; and for
  Metropolis a quarter of 16 spp is one iteration of its 262,144 chains against four (at 16 and 64
  it is 12 iterations more, beside a start of 17 iterations of its own).
- A first render of the N render's options, unmeasured, before the first pair (`warm_up_full`, by
  default at the GPU's sizes): PoCL compiles a kernel anew for the sizes of its first launches at a
  full render's size (seconds of wall time with an empty kernel cache), and most of the dearest
  first touches measured came in a technique's first full-size render (in a process, or after
  another technique's).
- `repeats` (by default at the GPU's sizes 7 for a path tracer, whose pair takes seconds and whose
  figure is near one pair's noise, and 3 for BDPT and Metropolis: GPU_REPEATS): the pair of renders is made that many times and each
  figure is the median of the pairs' figures, with the lowest and highest in `spread` (the JSON's
  `pairs` holds every pair's figures): a pair whose one render paid a dearer first touch is outvoted.
  `interval` says how far that median can be trusted: the order statistics that hold the true median
  with at least 95% confidence (median_interval; 7 pairs: the lowest and highest, 98.4%; 15 pairs: the
  4th and 12th, 96.5%). A limit inside it is neither met nor missed by the measurement.
Each render's minor page faults and the process's system CPU seconds are in its figures
(`page_faults`, `system_seconds`), so that a dear first touch shows.
The meter's own reading of the profiling events after a render (two queries per launch, for the
kernels' time: about 0.25 ns per path-tracing sample) is left out of the host's CPU time; the JSON
keeps it per render (`timing_cpu_seconds`). Its counting of the entry points stays in (a few
microseconds per launch).
Beside the host CPU per sample, `pass_cpu_ns_per_sample` counts only the thread's time inside the
technique's passes (run_pass): what the extra samples cost as well, without the start's and the
end's noise (but also without any per-sample work a technique defers to its end).
"""
import math
import time
from contextlib import contextmanager

from toolkit.api import as_scene, render, technique_options
from toolkit.core.render_options import with_fields
from toolkit.opencl.device import describe, get_queue
from toolkit.opencl.traffic import Traffic
from toolkit.techniques import family, get_technique

HOST_DEFAULT = ("pt_naive", "pt_inplace_regen", "pt_compact_regen", "bdpt_naive_connect", "bdpt_parallel_connect",
                "mlt")
RESOLUTION = (256, 256)
# An H200's sizes (results/gpu.md): 132 SMs x 2,048 resident work-items per stream and pool; Metropolis's
# chains are capped at 2^18 (toolkit/techniques/mlt.py).
GPU_SIZES = {"stream_size": 270_336, "pool_size": 270_336, "chains": 262_144}
GROWTH = 4   # the second render has GROWTH times the first one's samples
MEDIAN_CONFIDENCE = 0.95    # of the interval each timed figure's median is given with (median_interval)
# The figures that are times (noisy), for `spread`; the rest are counts, the same in every pair.
TIMED = ("host_cpu_ns_per_sample", "pass_cpu_ns_per_sample", "serial_ns_per_sample", "kernel_ns_per_sample",
         "wall_ns_per_sample", "kernel_share", "wait_cpu_ns_per_sample")


QUARTER = "N = spp / 4"
# Pairs of renders at the GPU's sizes by default (module docstring: Precision): a path tracer's pair
# takes seconds, and its host figure, about 2 ns per sample, is near the noise of one pair (1.7 to 3.0
# over three pairs, 2026-12-06); BDPT's and Metropolis's pairs take tens of seconds, their figures are larger.
GPU_REPEATS = {"pt": 7, "bdpt": 3, "mlt": 3}


def n_rule(technique, gpu_sizes):
    """How N is chosen for `technique` (the JSON's `n_rule`): `spp` for a path tracer, a quarter of
    it for BDPT and Metropolis, whose samples cost about ten times more; but `spp` for every technique
    at the GPU's sizes, where a render's fixed cost is seconds (module docstring: Precision)."""
    if family(technique) == "pt":
        return "N = spp"
    if gpu_sizes:
        return ("N = spp (at the GPU's sizes: enough samples for a difference above the first touch of the "
                "pool's or the chains' memory that every render pays)")
    return QUARTER


def spp_of(technique, spp, gpu_sizes=False):
    """N for `technique` by its n_rule (at least 1)."""
    return max(1, spp // 4) if n_rule(technique, gpu_sizes) == QUARTER else spp


def sized_options(technique, gpu_sizes):
    """The technique options that set its work in flight to GPU_SIZES (those its class takes), or none."""
    if not gpu_sizes:
        return {}
    takes = technique_options(get_technique(technique)[0])
    return {name: size for name, size in GPU_SIZES.items() if name in takes}


def metered_render(scene, technique, options, count_simd=False, warm_up=None):
    """One render under the meter: the traffic figures (traffic.Traffic), its wall seconds, the
    kernels' device seconds, its samples and its passes. `count_simd`: with the SIMD counters on (their
    figures read, as a render's stats read them, inside the metered time). `warm_up`: options of a
    small render made first, unmeasured: it builds the kernels, and its launches replace the kernels'
    last arguments (program.launch keeps them), which frees the device memory of the render before
    (a BDPT pool's vertex memory at a GPU's sizes is gigabytes: freeing it took this CPU's host
    0.2 to 0.4 s, which the next metered render's first launch would pay)."""
    if warm_up is not None:
        render(scene, technique, warm_up)
    cls = get_technique(technique)[0]
    before = _usage()
    with counted_passes(cls) as passes, Traffic() as traffic:
        result = render(scene, technique, with_fields(options, count_simd=count_simd, time_phases=True))
    after = _usage()
    stats = result.stats
    # the memory the render faulted in (first touches) and the whole process's system time (module
    # docstring: Precision): not per sample, a check that the two renders' fixed costs were alike
    faults = {key: after[key] - before[key] for key in before}
    figures = traffic.figures()
    # Reading every launch's profiling event, for the kernels' time, is the meter's work, not the
    # render's (a render without time_phases does none): its CPU time is left out of the host's.
    reading = stats["kernel_times_reading_seconds"]
    figures["cpu_seconds"] -= reading
    # Nor is its time inside waits for the device (traffic.py: the kernels' own, on some CPU runtimes).
    figures["cpu_seconds"] -= figures["wait_cpu_seconds"]
    return {**figures, **faults, "timing_cpu_seconds": reading, "pass_cpu_seconds": passes[1], "seconds": stats["seconds"],
            "kernel_seconds": sum(k["seconds"] for k in stats["kernel_times"].values()),
            "samples": round(stats["samples_per_second"] * stats["seconds"]), "passes": passes[0]}


def _usage():
    """The process's minor page faults and system CPU seconds so far; {} where the platform has no
    `resource` module (Windows): the figures are then left out, the meter still runs."""
    try:
        import resource
    except ImportError:
        return {}
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return {"page_faults": usage.ru_minflt, "system_seconds": usage.ru_stime}


@contextmanager
def counted_passes(cls):
    """Counts the calls of `cls.run_pass` (a technique's passes) while the block runs, and the thread
    CPU time spent in them, less its time inside waits for the device when a Traffic records (as the
    meter's host CPU); yields [count, seconds]."""
    count, real = [0, 0.0], cls.__dict__.get("run_pass")
    inherited = cls.run_pass

    def waits():
        return Traffic._active.wait_cpu_seconds if Traffic._active is not None else 0.0

    def run_pass(self, *args, **kwargs):
        count[0] += 1
        start, waited = time.thread_time(), waits()
        try:
            return inherited(self, *args, **kwargs)
        finally:
            count[1] += time.thread_time() - start - (waits() - waited)
    cls.run_pass = run_pass
    try:
        yield count
    finally:
        if real is None:
            del cls.run_pass
        else:
            cls.run_pass = real


def costs(first, second):
    """What the second render's extra samples cost, and its per-pass figures."""
    extra = second["samples"] - first["samples"]
    if extra <= 0:
        raise ValueError("the second render must have more samples than the first")

    def per_sample(key):
        return (second[key] - first[key]) / extra

    def per_million(key):
        return per_sample(key) * 1e6
    passes = max(second["passes"], 1)
    return {
        "host_cpu_ns_per_sample": per_sample("cpu_seconds") * 1e9,
        # the same, counting only the passes (run_pass): without the render's start and end, whose
        # host cost is the same in both renders but not its noise (Metropolis's start is 17 iterations)
        "pass_cpu_ns_per_sample": per_sample("pass_cpu_seconds") * 1e9,
        "serial_ns_per_sample": per_sample("serial_seconds") * 1e9,
        # the thread's CPU time inside waits for the device, left out of the host's (traffic.py)
        "wait_cpu_ns_per_sample": per_sample("wait_cpu_seconds") * 1e9,
        "kernel_ns_per_sample": per_sample("kernel_seconds") * 1e9,
        "wall_ns_per_sample": per_sample("seconds") * 1e9,
        "read_bytes_per_sample": per_sample("read_bytes"),
        "write_bytes_per_sample": per_sample("write_bytes"),
        "reads_per_million": per_million("reads"),
        "blocking_per_million": per_million("blocking_reads") + per_million("blocking_writes"),
        "drains_per_million": per_million("drains"),
        "launches_per_million": per_million("launches"),
        "blocking_per_pass": (second["blocking_reads"] + second["blocking_writes"]) / passes,
        "launches_per_pass": second["launches"] / passes,
        "kernel_share": second["kernel_seconds"] / second["seconds"] if second["seconds"] > 0 else 0.0,
    }


def median_of_pairs(pairs):
    """The figures of several pairs' `costs`: each the median of the pairs' (the middle one; for an
    even count the mean of the two middle ones), `spread`: the lowest and highest of each timed one,
    and `interval`: where each timed one's true median lies, with `interval_confidence` (median_interval)."""
    def median(values):
        v, k = sorted(values), len(values) // 2
        return v[k] if len(v) % 2 else (v[k - 1] + v[k]) / 2
    figures = {key: median([p[key] for p in pairs]) for key in pairs[0]}
    figures["spread"] = {key: [min(p[key] for p in pairs), max(p[key] for p in pairs)] for key in TIMED}
    intervals = {key: median_interval([p[key] for p in pairs]) for key in TIMED}
    figures["interval"] = {key: [low, high] for key, (low, high, _) in intervals.items()}
    figures["interval_confidence"] = intervals["host_cpu_ns_per_sample"][2]
    return figures


def median_interval(values, confidence=MEDIAN_CONFIDENCE):
    """(low, high, its confidence): the distribution-free interval for the median of what `values`
    sample, from their order statistics (e.g. Conover, Practical Nonparametric Statistics, sec. 3.2):
    the k-th smallest value lies below the median unless k or more of n values fall above it, which has
    the binomial probability P(B <= k - 1) with B ~ Binomial(n, 1/2); so [x_(k), x_(n+1-k)] holds the
    median with confidence 1 - 2 P(B <= k - 1). k is the largest that keeps `confidence` (15 values:
    the 4th and 12th, 96.5%); with too few values for it, the whole range and what it gives (3 values:
    75%). A pair's figure is no normal variable (a pair that paid a dear first touch is far out), so no
    standard error of a mean: the pairs' own order says how far the median can be trusted."""
    v, n = sorted(values), len(values)
    below = lambda k: sum(math.comb(n, i) for i in range(k)) / 2 ** n     # P(B <= k - 1)
    k = 1
    while k + 1 <= (n + 1) // 2 and 1 - 2 * below(k + 1) >= confidence:
        k += 1
    return v[k - 1], v[n - k], 1 - 2 * below(k)


def host_meter(scene=None, techniques=HOST_DEFAULT, options=None, spp=16, gpu_sizes=False, count_simd=False,
               repeats=None, warm_up_full=None, **fields):
    """The host meter's report: for each technique, its renders at N and GROWTH x N samples per pixel
    (N: spp_of(technique, spp, gpu_sizes)) and what the extra samples cost (`costs`). `options`: a RenderOptions
    (its fields as keywords on top); resolution None is RESOLUTION. A small render precedes each measured one
    (metered_render's warm_up), so no build and no freeing of the render before is measured; and with
    `warm_up_full` (None: at the GPU's sizes only), a render of the N render's options, unmeasured,
    before the first pair (module docstring: Precision). `count_simd`: the renders count SIMD
    efficiency. `repeats`: the pair of renders made that many times (None: GPU_REPEATS of the
    technique's family at the GPU's sizes, else 1), each figure the median of the pairs'
    (median_of_pairs); `renders` are the first pair's."""
    if warm_up_full is None:
        warm_up_full = bool(gpu_sizes)
    if repeats is not None and (isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1):
        raise ValueError(f"repeats must be a whole number of at least 1, got {repeats!r}")
    options = with_fields(options, **fields)
    options = with_fields(options, resolution=options.resolution or RESOLUTION)
    scene = as_scene(scene)
    report = {"scene": scene.name, "resolution": list(options.resolution), "gpu_sizes": bool(gpu_sizes),
              "sizes": GPU_SIZES if gpu_sizes else "the device's own", "count_simd": bool(count_simd),
              "repeats": repeats if repeats is not None else (dict(GPU_REPEATS) if gpu_sizes else 1),
              "warm_up_full": bool(warm_up_full), "techniques": {}}
    for technique in techniques:
        pairs_made = repeats or (GPU_REPEATS[family(technique)] if gpu_sizes else 1)
        own = {**options.technique_options, **sized_options(technique, gpu_sizes)}
        base = with_fields(options, technique_options=own)
        n = spp_of(technique, spp, gpu_sizes)
        warm_up = with_fields(base, spp=1, resolution=(16, 16), count_simd=count_simd)
        renders, pairs = None, []
        if warm_up_full:
            render(scene, technique, with_fields(base, spp=n, count_simd=count_simd))
        for _ in range(pairs_made):
            first, second = (metered_render(scene, technique, with_fields(base, spp=k), count_simd, warm_up=warm_up)
                             for k in (n, GROWTH * n))
            renders = renders or [first, second]
            pairs.append(costs(first, second))
        report["device"] = describe(get_queue(base.device, base.lanes).device)
        row = {"spp": [n, GROWTH * n], "n_rule": n_rule(technique, gpu_sizes), "renders": renders, "repeats": pairs_made}
        report["techniques"][technique] = {**row, **median_of_pairs(pairs), "pairs": pairs} if pairs_made > 1 else \
            {**row, **pairs[0]}
    return report


def format_host_meter(report):
    sizes = "the GPU's sizes (" + ", ".join(f"{k} {v:,}" for k, v in GPU_SIZES.items()) + ")" \
        if report["gpu_sizes"] else "the device's own sizes"
    counters = ", SIMD counters on" if report.get("count_simd") else ""
    repeats = report.get("repeats", 1)
    if isinstance(repeats, dict):
        counters += ", the median of " + ", ".join(f"{n} pairs of renders ({what})" for what, n in repeats.items())
    elif repeats > 1:
        counters += f", the median of {repeats} pairs of renders"
    lines = [f"host meter: {report['scene']} {report['resolution'][0]}x{report['resolution'][1]} at {sizes}{counters}, "
             f"on {report.get('device', '?')}; what the second render's {GROWTH - 1}N more samples cost "
             f"(N: the first render's samples per pixel)",
             f"{'technique':<24}{'N, 4N spp':>10}{'kernels 4N s':>13}{'kernel share':>13}{'host CPU ns/sample':>19}"
             f"{'serial ns':>10}{'read B/sample':>14}{'written B':>10}{'reads/M':>9}{'blocking/M':>11}"
             f"{'launches/M':>11}{'blocking/pass':>14}{'launches/pass':>14}"]
    for name, row in report["techniques"].items():
        lines.append(f"{name:<24}{'%d, %d' % tuple(row['spp']):>10}{row['renders'][1]['kernel_seconds']:>13.2f}"
                     f"{row['kernel_share']:>13.0%}{row['host_cpu_ns_per_sample']:>19,.1f}"
                     f"{row['serial_ns_per_sample']:>10,.1f}{row['read_bytes_per_sample']:>14,.2f}"
                     f"{row['write_bytes_per_sample']:>10,.2f}{row['reads_per_million']:>9,.1f}"
                     f"{row['blocking_per_million']:>11,.1f}{row['launches_per_million']:>11,.1f}"
                     f"{row['blocking_per_pass']:>14,.1f}{row['launches_per_pass']:>14,.1f}")
    for name, row in report["techniques"].items():
        if "spread" in row:
            low, high = row["spread"]["host_cpu_ns_per_sample"]
            line = f"{name}: host CPU ns/sample from {low:,.1f} to {high:,.1f} over the {row['repeats']} pairs"
            if "interval" in row:
                a, b = row["interval"]["host_cpu_ns_per_sample"]
                line += f"; their median within {a:,.1f} to {b:,.1f} ({row['interval_confidence']:.1%} confidence)"
            lines.append(line)
    for name, row in report["techniques"].items():
        if "pass_cpu_ns_per_sample" in row:
            lines.append(f"{name}: host CPU inside its passes {row['pass_cpu_ns_per_sample']:,.1f} ns/sample")
    waits = [row.get("wait_cpu_ns_per_sample", 0.0) for row in report["techniques"].values()]
    if waits and max(waits) >= 1.0:
        lines.append("left out of host CPU, the thread's time inside waits for the device (ns/sample; where the "
                     "waiting thread runs the kernels, as Intel's CPU runtime does, the kernels' own time): "
                     + ", ".join(f"{name} {row.get('wait_cpu_ns_per_sample', 0.0):,.1f}"
                                 for name, row in report["techniques"].items()))
    lines.append("host CPU: the CPU time of the thread that drives the queue, outside its waits for the device; "
                 "serial: the part of it while the device's queue was empty (from a blocking read, finish or wait "
                 "to the next launch); blocking: blocking reads and writes; per pass: in the 4N render. Kernels: "
                 "OpenCL profiling events.")
    return "\n".join(lines)


def markdown_table(report):
    """The report's figures per technique as a Markdown table (for a results note)."""
    lines = ["| technique | N, 4N spp | kernels 4N (s) | kernels' share of wall | host CPU ns/sample | of it serial | "
             "bytes read/sample | bytes written/sample | reads/M samples | blocking/M samples | launches/M samples | "
             "blocking/pass | launches/pass |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name, r in report["techniques"].items():
        lines.append(f"| {name} | {r['spp'][0]}, {r['spp'][1]} | {r['renders'][1]['kernel_seconds']:.2f} | "
                     f"{r['kernel_share']:.0%} | {r['host_cpu_ns_per_sample']:,.1f} | {r['serial_ns_per_sample']:,.1f} | "
                     f"{r['read_bytes_per_sample']:,.2f} | {r['write_bytes_per_sample']:,.2f} | "
                     f"{r['reads_per_million']:,.1f} | {r['blocking_per_million']:,.1f} | "
                     f"{r['launches_per_million']:,.1f} | {r['blocking_per_pass']:,.1f} | {r['launches_per_pass']:,.1f} |")
    return "\n".join(lines)
