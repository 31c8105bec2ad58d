"""The host meter (issue 48, item 1): toolkit/opencl/traffic.py's counts on cases whose answer is
known (a made-up sequence of commands; pt_naive's passes), the same counts from an independent
counter (pyopencl's lower entry points in pyopencl._cl, and the profiling events of the launches),
and `bench --host` on the command line."""
import json

import numpy as np
import pyopencl as cl
import pyopencl._cl as _cl
import pytest

from toolkit.api import render
from toolkit.core.layout import FILM_PIXEL
from toolkit.measure.host_meter import costs, metered_render, spp_of
from toolkit.opencl import program
from toolkit.opencl.traffic import Traffic
from test_cli import run_cli

# A tiny kernel of the test's own: the meter counts commands, whatever they run.
ADD_ONE = "__kernel void add_one(__global int *x, int n) { int i = get_global_id(0); if (i < n) x[i] += 1; }"


def test_a_known_sequence_of_commands_is_counted_exactly(queue):
    # The program kept alive beside its kernel: Intel's CPU runtime refuses a kernel's program
    # (clRetainProgram: INVALID_PROGRAM) once the host has released it, and launch asks for it.
    built = cl.Program(queue.context, ADD_ONE).build()
    kernel = cl.Kernel(built, "add_one")
    n = 1000
    host = np.zeros(n, np.int32)
    buffer = cl.Buffer(queue.context, cl.mem_flags.READ_WRITE, 4 * n)
    other = cl.Buffer(queue.context, cl.mem_flags.READ_WRITE, 4 * n)
    with Traffic() as traffic:
        cl.enqueue_copy(queue, buffer, host)                                  # a blocking write: 4,000 bytes
        cl.enqueue_fill_buffer(queue, other, np.int32(0), 0, 4 * n)           # a fill: no host bytes
        for _ in range(3):
            program.launch(queue, kernel, n, buffer, np.int32(n), local_size=64)
        cl.enqueue_copy(queue, host, buffer)                                  # a blocking read: a drain
        program.launch(queue, kernel, n, buffer, np.int32(n), local_size=64)
        early = cl.enqueue_copy(queue, host[:10], buffer, is_blocking=False)  # 40 bytes, not waited for yet
        program.launch(queue, kernel, n, buffer, np.int32(n), local_size=64)
        early.wait()                           # a kernel is queued behind it: not a drain
        late = cl.enqueue_copy(queue, host, buffer, is_blocking=False)
        late.wait()                            # the last command queued: a drain
        cl.enqueue_copy(queue, other, buffer)                                 # on the device: no host bytes
        queue.finish()                                                        # a drain
    assert np.all(host == 5)
    times = {"serial_seconds": 0, "cpu_seconds": 0, "wait_cpu_seconds": 0}
    assert traffic.figures() | times == {
        "launches": 5, "fills": 1, "reads": 3, "blocking_reads": 1, "read_bytes": 4 * n + 40 + 4 * n,
        "writes": 1, "blocking_writes": 1, "write_bytes": 4 * n, "device_copies": 1,
        "drains": 4, **times}   # blocking write, blocking read, late.wait, finish
    assert 0 < traffic.serial_seconds <= traffic.cpu_seconds
    assert 0 <= traffic.wait_cpu_seconds <= traffic.cpu_seconds
    # Restored after: nothing counts outside the recording.
    cl.enqueue_copy(queue, host, buffer)
    assert traffic.reads == 3 and cl.enqueue_copy.__module__ == "pyopencl"


def test_the_threads_time_inside_waits_is_kept_apart(queue, monkeypatch):
    """A wait whose thread works (as Intel's CPU runtime's waiter runs the kernels) counts in
    wait_cpu_seconds, a blocking read, Event.wait and finish alike; the work between them does not."""
    import time

    def burn(seconds):
        start = time.thread_time()
        while time.thread_time() - start < seconds:
            pass
    real_wait, real_finish, real_copy = cl.Event.wait, cl.CommandQueue.finish, cl.enqueue_copy
    monkeypatch.setattr(cl.Event, "wait", lambda event: (burn(0.02), real_wait(event))[1])
    monkeypatch.setattr(cl.CommandQueue, "finish", lambda q: (burn(0.02), real_finish(q))[1])
    monkeypatch.setattr(cl, "enqueue_copy", lambda *a, **k: (burn(0.02), real_copy(*a, **k))[1])
    host, buffer = np.zeros(4, np.int32), cl.Buffer(queue.context, cl.mem_flags.READ_WRITE, 16)
    with Traffic() as traffic:
        cl.enqueue_copy(queue, host, buffer)                          # blocking: 0.02 s inside
        cl.enqueue_copy(queue, host, buffer, is_blocking=False).wait()  # 0.02 s not waiting, 0.02 s waiting
        queue.finish()                                                # 0.02 s
        burn(0.03)                                                    # the host's own work
    assert 0.06 <= traffic.wait_cpu_seconds < 0.08
    assert 0.05 <= traffic.cpu_seconds - traffic.wait_cpu_seconds < 0.07


def test_only_the_recording_thread_is_counted(queue):
    import threading
    host, buffer = np.zeros(4, np.int32), cl.Buffer(queue.context, cl.mem_flags.READ_WRITE, 16)
    with Traffic() as traffic:
        other = threading.Thread(target=lambda: cl.enqueue_copy(queue, host, buffer))
        other.start()
        other.join()
        cl.enqueue_copy(queue, host, buffer)
    assert traffic.reads == 1


def test_pt_naive_known_counts_per_pass_with_the_film_on_the_host(cornell_box, monkeypatch):
    """pt_naive, counters off, one sample per pixel per pass, the film added on the host (a device
    without float64): each pass fills its output, launches its kernel and the film's sum (2
    launches), and queues one asynchronous read of a FilmPixel per pixel; no pass blocks. The
    extra passes of the second render cost exactly that."""
    from toolkit.techniques.base import Technique
    monkeypatch.setattr(Technique, "film_on_device", False)
    width, height = 8, 4
    first, second = pt_naive_in_passes_of_one_sample(cornell_box, width, height)
    for r in (first, second):
        assert r["launches"] == 2 * r["passes"] and r["fills"] == r["passes"]
        assert r["reads"] == r["passes"] and r["blocking_reads"] == 0
        assert r["read_bytes"] == r["passes"] * width * height * FILM_PIXEL.dtype.itemsize
        assert r["samples"] == width * height * r["passes"]
    extra = costs(first, second)
    assert extra["read_bytes_per_sample"] == pytest.approx(FILM_PIXEL.dtype.itemsize)   # one pixel's sums per sample
    assert extra["launches_per_million"] == pytest.approx(2e6 / (width * height))
    assert extra["blocking_per_pass"] == 0 and extra["launches_per_pass"] == 2
    assert 0 < extra["kernel_share"] <= 1


def test_pt_naive_known_counts_per_pass_with_the_film_on_the_device(cornell_box, queue):
    """The same where the device has float64 (toolkit/opencl/device_film.py): each pass launches
    its kernel, the film's sum and its addition to the film on the device (3 launches); the film
    fills its two buffers once and is read once, at the end: 6 doubles and 2 ints per pixel, in
    two reads. The extra passes read nothing."""
    from toolkit.opencl.device_film import has_fp64
    if not has_fp64(queue.device):
        pytest.skip("the device has no cl_khr_fp64: its film is added on the host")
    width, height = 8, 4
    first, second = pt_naive_in_passes_of_one_sample(cornell_box, width, height)
    for r in (first, second):
        assert r["launches"] == 3 * r["passes"] and r["fills"] == r["passes"] + 2
        assert r["reads"] == 2 and r["blocking_reads"] == 0
        assert r["read_bytes"] == width * height * (6 * 8 + 2 * 4)
        assert r["samples"] == width * height * r["passes"]
    extra = costs(first, second)
    assert extra["read_bytes_per_sample"] == 0 and extra["reads_per_million"] == 0
    assert extra["launches_per_million"] == pytest.approx(3e6 / (width * height))
    assert extra["blocking_per_pass"] == 0 and extra["launches_per_pass"] == 3


def test_counted_renders_read_their_counters_once(cornell_box):
    """With the SIMD counters on, pt_compact_regen's steps queue their sums on the device and the host
    reads the step log once, when the render's figures are collected: the blocking reads of an
    uncounted render plus one (before the step log: one per step, 58 per pass at the CPU's sizes)."""
    options = options_of(dict(resolution=(16, 16), spp=4, technique_options={"stream_size": 256}))
    counted = metered_render(cornell_box, "pt_compact_regen", options, count_simd=True)
    uncounted = metered_render(cornell_box, "pt_compact_regen", options)
    assert counted["passes"] == uncounted["passes"] == 1
    assert counted["blocking_reads"] == uncounted["blocking_reads"] + 1
    assert counted["launches"] > uncounted["launches"]     # a sum per step: launches, not reads


def pt_naive_in_passes_of_one_sample(scene, width, height):
    """pt_naive metered at 2 and 5 spp, one sample per pixel per pass: (first, second)."""
    options = dict(resolution=(width, height), technique_options={"pass_spp": 1})
    first = metered_render(scene, "pt_naive", options_of(options, spp=2))
    second = metered_render(scene, "pt_naive", options_of(options, spp=5))
    assert (first["passes"], second["passes"]) == (2, 5)
    return first, second


def options_of(fields, **more):
    from toolkit.core.render_options import with_fields
    return with_fields(None, **{**fields, **more})


class LowerCount:
    """An independent count: pyopencl's lower entry points (pyopencl._cl, which enqueue_copy and
    enqueue_fill_buffer call), patched for the block."""

    def __init__(self, monkeypatch):
        self.reads = self.blocking_reads = self.read_bytes = self.writes = self.write_bytes = self.fills = 0
        real_read, real_write, real_fill = _cl._enqueue_read_buffer, _cl._enqueue_write_buffer, _cl._enqueue_fill_buffer

        def read(queue, mem, hostbuf, *args, **kwargs):
            self.reads += 1
            self.blocking_reads += bool(kwargs.get("is_blocking", True))
            self.read_bytes += np.asarray(hostbuf).nbytes
            return real_read(queue, mem, hostbuf, *args, **kwargs)

        def write(queue, mem, hostbuf, *args, **kwargs):
            self.writes += 1
            self.write_bytes += np.asarray(hostbuf).nbytes
            return real_write(queue, mem, hostbuf, *args, **kwargs)

        def fill(*args, **kwargs):
            self.fills += 1
            return real_fill(*args, **kwargs)
        monkeypatch.setattr(_cl, "_enqueue_read_buffer", read)
        monkeypatch.setattr(_cl, "_enqueue_write_buffer", write)
        monkeypatch.setattr(_cl, "_enqueue_fill_buffer", fill)


@pytest.mark.parametrize("technique", ["pt_compact_regen", "bdpt_naive_connect", "mlt"])
def test_an_independent_count_agrees_with_the_meter(monkeypatch, cornell_box, technique):
    """The meter's counts (pyopencl's enqueue_* wrapped) against pyopencl._cl's entry points and the
    profiling events of every launch (program.launch's hook, toolkit/opencl/kernel_times.py)."""
    lower = LowerCount(monkeypatch)
    options = dict(resolution=(16, 16), spp=spp_of(technique, 8), count_simd=False, time_phases=True,
                   technique_options={"stream_size": 1024} if technique == "pt_compact_regen" else {})
    with Traffic() as traffic:
        result = render(cornell_box, technique, options_of(options))
    events = sum(k["launches"] for k in result.stats["kernel_times"].values())
    assert traffic.launches == events > 0
    assert (traffic.reads, traffic.blocking_reads, traffic.read_bytes) == (lower.reads, lower.blocking_reads,
                                                                         lower.read_bytes)
    assert (traffic.writes, traffic.write_bytes, traffic.fills) == (lower.writes, lower.write_bytes, lower.fills)
    assert traffic.reads > 0 and traffic.fills > 0     # every technique reads its film back: counts to agree on


def test_bench_host_on_the_command_line():
    result = run_cli("bench", "--host", "--techniques", "pt_naive", "--resolution", "16x8", "--spp", "2", "--json")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.strip().splitlines()
    assert lines[0].startswith("host meter: cornell_box 16x8")
    report = json.loads(lines[-1])
    row = report["techniques"]["pt_naive"]
    from toolkit.opencl.device import get_queue
    from toolkit.opencl.device_film import has_fp64
    film_launches = 2 if has_fp64(get_queue().device) else 1    # the film's sum, and its addition on the device
    assert row["spp"] == [2, 8] and row["blocking_per_pass"] == 0 and row["launches_per_pass"] == 1 + film_launches
    assert row["read_bytes_per_sample"] == 0   # 8 spp in one pass: no more reads than 2 spp
    counted = run_cli("bench", "--host", "--count-simd", "--techniques", "pt_compact_regen", "--resolution", "16x8",
                      "--spp", "2", "--json")
    assert counted.returncode == 0, counted.stderr
    assert "SIMD counters on" in counted.stdout.splitlines()[0] and json.loads(counted.stdout.splitlines()[-1])["count_simd"]
    refused = run_cli("bench", "--gpu-sizes")
    assert refused.returncode == 2 and "--gpu-sizes applies to the host meter only" in refused.stderr
    assert "Traceback" not in refused.stderr
    refused = run_cli("bench", "--count-simd")
    assert refused.returncode == 2 and "--count-simd applies to the host meter only" in refused.stderr


def test_median_of_pairs_takes_each_figure_s_middle_value_and_its_spread():
    from toolkit.measure.host_meter import TIMED, median_of_pairs
    pairs = [{key: v for key in TIMED} | {"launches_per_pass": 7} for v in (5.0, -1.0, 2.0)]
    figures = median_of_pairs(pairs)
    assert figures["host_cpu_ns_per_sample"] == 2.0 and figures["launches_per_pass"] == 7
    assert figures["spread"]["host_cpu_ns_per_sample"] == [-1.0, 5.0]
    assert median_of_pairs(pairs[:2])["kernel_share"] == 2.0           # even: the mean of the middle two
    assert figures["interval"]["host_cpu_ns_per_sample"] == [-1.0, 5.0] and figures["interval_confidence"] == 0.75


def test_the_median_s_interval_comes_from_the_order_statistics_a_binomial_gives():
    """median_interval: [x_(k), x_(n+1-k)] with k the largest whose confidence, 1 - 2 P(B <= k - 1) for
    B ~ Binomial(n, 1/2), is at least 95%; its confidence checked against the binomial's probabilities
    summed by hand, and by drawing: the true median of a skewed distribution falls outside in about
    1 - confidence of the samples (fixed seed; the tolerance is 4 binomial standard errors of that rate)."""
    from toolkit.measure.host_meter import median_interval
    values = [float(v) for v in range(15, 0, -1)]                  # 15 values, unsorted
    assert median_interval(values) == (4.0, 12.0, 1 - 2 * (1 + 15 + 105 + 455) / 2 ** 15)   # k = 4: 96.5%
    assert median_interval(values, confidence=0.8)[:2] == (5.0, 11.0)   # k = 5: 1 - 2 * 1941 / 2^15 = 88.2%
    assert median_interval([3.0, 1.0, 2.0, 7.0, 5.0, 4.0, 6.0]) == (1.0, 7.0, 1 - 2 / 2 ** 7)   # k = 2 gives 87.5%
    assert median_interval([2.0, -1.0, 5.0]) == (-1.0, 5.0, 0.75)
    rng = np.random.default_rng(48)
    samples = rng.lognormal(0.0, 1.0, size=(4000, 15))             # the median of lognormal(0, 1) is 1
    outside = np.mean([not (low <= 1.0 <= high) for low, high, _ in map(median_interval, samples)])
    confidence = median_interval(samples[0])[2]
    rate = 1 - confidence
    assert abs(outside - rate) <= 4 * np.sqrt(rate * (1 - rate) / len(samples))


def test_every_technique_at_the_gpu_s_sizes_takes_n_equal_to_spp():
    """At the GPU's sizes a quarter of 16 spp is one iteration of Metropolis's 262,144 chains at
    256x256, and one pool of BDPT's, beside a first touch of gigabytes that every render pays: N = spp
    there (12 iterations more, not 3); elsewhere a quarter for BDPT and mlt."""
    assert spp_of("mlt", 16, gpu_sizes=True) == 16 and spp_of("mlt", 16) == 4
    assert spp_of("bdpt_parallel_connect", 16, gpu_sizes=True) == 16 and spp_of("bdpt_naive_connect", 16) == 4
    assert spp_of("pt_naive", 16, gpu_sizes=True) == 16 == spp_of("pt_naive", 16)


def test_repeated_pairs_report_the_median_and_exact_counts(cornell_box, monkeypatch):
    """repeats=2: each pair of pt_naive renders (film on the host, one sample per pass) has the same
    counts as one pair (exactly: 2 launches and one read per pass), and the report says so."""
    from toolkit.measure.host_meter import host_meter
    from toolkit.techniques.base import Technique
    monkeypatch.setattr(Technique, "film_on_device", False)
    report = host_meter(cornell_box, ("pt_naive",), spp=2, repeats=2, resolution=(8, 4),
                        technique_options={"pass_spp": 1})
    row = report["techniques"]["pt_naive"]
    assert report["repeats"] == 2 and len(row["pairs"]) == 2 and row["spp"] == [2, 8]
    for figures in row["pairs"] + [row]:
        assert figures["launches_per_pass"] == 2 and figures["blocking_per_pass"] == 0
        assert figures["launches_per_million"] == pytest.approx(2e6 / 32)
    low, high = row["spread"]["host_cpu_ns_per_sample"]
    assert low <= row["host_cpu_ns_per_sample"] <= high
    for r in row["renders"]:    # the passes' share of the thread's time: part of it
        assert 0 < r["pass_cpu_seconds"] <= r["cpu_seconds"]
        assert r["timing_cpu_seconds"] > 0    # the meter's reading of the events, left out of cpu_seconds
        assert r["page_faults"] >= 0 and r["system_seconds"] >= 0     # the fixed cost's check, per render
    with pytest.raises(ValueError, match="repeats"):
        host_meter(cornell_box, ("pt_naive",), repeats=0)


def test_the_meter_renders_once_unmeasured_at_n_before_its_pairs(cornell_box, monkeypatch):
    """warm_up_full (the default at the GPU's sizes): one render of the N render's options before the
    first pair (PoCL's kernels for a full render's sizes, the first touch after another technique's),
    then per measured render the small warm-up; at the device's own sizes neither it nor more than one
    pair by default (GPU_REPEATS pairs at the GPU's)."""
    import toolkit.measure.host_meter as meter
    seen = []
    real = meter.render

    def render(scene, technique, options=None, **fields):
        seen.append((options.spp, tuple(options.resolution), options.time_phases))
        return real(scene, technique, options, **fields)
    monkeypatch.setattr(meter, "render", render)
    report = meter.host_meter(cornell_box, ("pt_naive",), spp=2, resolution=(8, 4), warm_up_full=True)
    assert report["repeats"] == 1 and report["warm_up_full"]
    assert seen == [(2, (8, 4), False), (1, (16, 16), False), (2, (8, 4), True),
                    (1, (16, 16), False), (8, (8, 4), True)]
    seen.clear()
    report = meter.host_meter(cornell_box, ("pt_naive",), spp=2, resolution=(8, 4))
    assert [spp for spp, _, _ in seen] == [1, 2, 1, 8] and not report["warm_up_full"]
    # at the GPU's sizes, the pairs a technique's family gets (7 for a path tracer)
    monkeypatch.setattr(meter, "GPU_SIZES", {})
    monkeypatch.setattr(meter, "metered_render", lambda *args, **kwargs: seen.append("pair") or
                        {key: 1.0 for key in ("samples", "passes", "cpu_seconds", "pass_cpu_seconds", "serial_seconds",
                                              "kernel_seconds", "seconds", "read_bytes", "write_bytes", "reads", "wait_cpu_seconds",
                                              "blocking_reads", "blocking_writes", "drains", "launches")}
                        | {"samples": len(seen)})
    seen.clear()
    report = meter.host_meter(cornell_box, ("pt_naive",), spp=2, resolution=(8, 4), gpu_sizes=True, warm_up_full=False)
    assert seen.count("pair") == 2 * meter.GPU_REPEATS["pt"] == 14 and report["techniques"]["pt_naive"]["repeats"] == 7
