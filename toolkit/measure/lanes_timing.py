"""Timing techniques with SIMD lanes off and on, on Intel's CPU runtime, as tutorials 02 and 03
do ("Lanes on a CPU"): where the runtime is, an interleaved timing of both settings, each
technique's ratio to a baseline run by run, and the table the tutorials print.
`python -m toolkit bench --device intel --lanes off,on` measures the same on the command line, with
the same interleaved runs (toolkit/measure/bench.py)."""
import platform
import statistics

from toolkit.core.render_options import RenderOptions
from toolkit.measure.bench import interleaved_rates
from toolkit.opencl import lanes as cpu_lanes
from toolkit.opencl.device import candidates


def intel_runtime():
    """(the candidate, None) for Intel's CPU runtime, or (None, why it cannot be timed here)."""
    found = [c for c in candidates() if "Intel" in c.device.platform.name and cpu_lanes.can_choose(c.device)]
    usable = [c for c in found if c.usable]
    fixed, variable = cpu_lanes.fixed_by_environment()
    if fixed:
        return None, f"{variable} is set, which fixes Intel's vectorizer for the whole process (unset it)"
    if usable:
        return usable[0], None
    if found:
        return None, f"Intel's CPU runtime is installed but not usable: {found[0].reason}"
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return None, f"Intel's CPU runtime exists for x86-64 only, and this machine is {platform.machine()}"
    return None, ("Intel's CPU runtime is not installed, or did not load (x86-64 Linux: pip install "
                  "intel-opencl-rt; python -m toolkit devices says more)")


def time_lanes(runtime, scene, techniques, resolution, spp, repeats, options, seed=0):
    """Samples/s of each technique with lanes off and on, on `runtime` (from intel_runtime), in
    bench's interleaved runs after its warm-up. `options`: {technique: its options}. Returns
    ({(technique, setting): [samples/s per repeat]}, {setting: the widest vector the compiler used})."""
    rows = [(name, setting) for setting in ("off", "on") for name in techniques]
    given = RenderOptions(seed=seed, resolution=(resolution, resolution), device=runtime.selector)
    rates, stats = interleaved_rates(scene, rows, lambda name: spp, repeats, given, technique_options=options)
    widths = {}
    for (_, setting), st in stats.items():
        widths[setting] = max(widths.get(setting, 1), st["vector_width"] or 1)
    return rates, widths


def ratio_in_each_run(rates, name, base, setting):
    """name's samples/s over base's, repeat by repeat (the two ran side by side), then the median."""
    return statistics.median(a / b for a, b in zip(rates[(name, setting)], rates[(base, setting)]))


def format_lanes_table(rates, base, talk):
    """Each technique of `talk` ({technique: the talk's ratio, as text}): its samples/s with lanes
    off and on, and its ratio to `base` both ways beside the talk's."""
    lines = [f"{'technique':<24}{'lanes off':>12}{'lanes on':>12}{'ratio to ' + base + ', off':>34}{'on':>7}"
             f"{'the talk (GPU)':>16}"]
    for name in talk:
        off, on = (statistics.median(rates[(name, s)]) for s in ("off", "on"))
        lines.append(f"{name:<24}{off:>12,.0f}{on:>12,.0f}{ratio_in_each_run(rates, name, base, 'off'):>34.2f}"
                     f"{ratio_in_each_run(rates, name, base, 'on'):>7.2f}{talk[name]:>16}")
    lines.append("samples/s: medians of the interleaved runs; ratios: the median of each run's ratio")
    return "\n".join(lines)


def describe_cpu(runtime, widths):
    """The CPU, its hardware threads, and the vector width the compiler used with lanes on and off."""
    bits = 32 * widths["on"]
    isa = {4: "SSE", 8: "AVX2", 16: "AVX-512"}.get(widths["on"], "its vector unit")
    return (f"CPU: {runtime.device.name.strip()}, {runtime.device.max_compute_units} hardware threads; "
            f"with lanes on the compiler ran {widths['on']} work-items per vector ({bits}-bit registers, {isa}), "
            f"with lanes off {widths['off']}")
