"""`python -m toolkit demo --bench`: what the live view costs. For each technique, alone in the
view: the frames per second the page gets, and its samples/s against a plain render of the same
technique (toolkit.render with the same SIMD counters on, as the view has them), in interleaved
runs (plain, live, plain, live, ...) so that a slow moment of the machine hits both.

The live runs do what the server does for a tab, without a browser: the render thread renders,
the view redraws every PERIOD_MS from its snapshot, and each change to the page's models is
serialized as the Bokeh message the server would send (PATCH-DOC, with the images as binary
buffers). A browser's own drawing runs in its own process and is not counted. This prints
ratios; it asserts nothing (a timing depends on the machine and its load).
"""
import statistics
import time

from toolkit.api import render
from toolkit.techniques import get_technique
from toolkit.demo.settings import Settings
from toolkit.demo.view import PERIOD_MS, DemoView


def bench_live_view(scenes, settings=Settings(), device=None, seconds=6.0, repeats=3):
    """{technique: figures} for each technique of `settings`, at its resolution and seed."""
    scene = scenes.load(settings.scene)
    width, height = settings.resolution
    report = {}
    for technique in settings.techniques:
        # A warm-up builds the kernels (or finds them built) and measures the rate, to size the plain runs.
        warm = render(scene, technique=technique, spp=1, resolution=(width, height), seed=settings.seed,
                      device=device, lanes=settings.lanes)
        spp = max(1, round(seconds * warm.stats["samples_per_second"] / (width * height)))
        plain, live, fps = [], [], []
        for r in range(repeats):
            result = render(scene, technique=technique, spp=spp, resolution=(width, height), seed=settings.seed,
                            device=device, lanes=settings.lanes)
            plain.append(result.stats["samples_per_second"])
            rate, frames = live_run(scenes, settings.changed(techniques=(technique,)), device, seconds)
            live.append(rate)
            fps.append(frames)
        plain_rate, live_rate = statistics.median(plain), statistics.median(live)
        report[technique] = {"plain_samples_per_second": plain_rate, "live_samples_per_second": live_rate,
                             "cost": 1 - live_rate / plain_rate, "frames_per_second": statistics.median(fps),
                             "plain_runs": plain, "live_runs": live, "fps_runs": fps,
                             "rate_unit": "mutations" if get_technique(technique)[0].family == "mlt" else "samples"}
    return {"scene": settings.scene, "resolution": [width, height], "seconds": seconds, "repeats": repeats,
            "device": warm.stats["device"], "techniques": report}


def live_run(scenes, settings, device, seconds):
    """(samples/s, frames shown per second) of `seconds` of the live view, after its first frame."""
    from bokeh.document import Document
    from bokeh.protocol import Protocol
    view = DemoView(scenes, settings, device)
    document = Document()
    document.add_root(view.panel.get_root(document))
    protocol = Protocol()
    document.on_change(lambda event: protocol.create("PATCH-DOC", [event]))   # the server's message to the tab
    view.worker.start()
    name = settings.techniques[0]
    try:
        first = wait_for_frame(view, name, after=0)
        start, shown, frame = time.monotonic(), 0, first
        while time.monotonic() - start < seconds:
            view.refresh()
            newest = view.worker.snapshot().frames[name]
            if newest.number != frame.number:
                shown, frame = shown + 1, newest
            time.sleep(PERIOD_MS / 1000)
        last = wait_for_frame(view, name, after=frame.number)
    finally:
        view.stop()
    rate = (last.samples - first.samples) / (last.published - first.published)
    return rate, shown / (time.monotonic() - start)


def wait_for_frame(view, name, after, timeout=300):
    """The first frame of `name` numbered above `after`, redrawing meanwhile as the page would."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        view.refresh()
        snap = view.worker.snapshot()
        if snap.error:
            raise RuntimeError(f"the live view stopped: {snap.error}")
        frame = snap.frames.get(name)
        if frame is not None and frame.number > after:
            return frame
        time.sleep(0.01)
    raise TimeoutError(f"{name}: no frame in {timeout} s")


def format_live_bench(report):
    width, height = report["resolution"]
    lines = [f"demo --bench: {report['scene']} {width}x{height}, {report['seconds']:.0f} s of live view per run, "
             f"median of {report['repeats']} interleaved runs (plain, live) on {report['device']}",
             f"{'technique':<24}{'frames/s':>10}{'plain /s':>14}{'live /s':>14}{'live / plain':>14}{'cost':>8}"]
    for name, row in report["techniques"].items():
        ratio = row["live_samples_per_second"] / row["plain_samples_per_second"]
        lines.append(f"{name:<24}{row['frames_per_second']:>10.1f}{row['plain_samples_per_second']:>14,.0f}"
                     f"{row['live_samples_per_second']:>14,.0f}{ratio:>14.2f}{row['cost']:>8.1%}")
    lines.append("plain: toolkit.render with the SIMD counters on, as the view runs them; live: the technique alone in "
                 "the view, rendering and redrawing; /s: samples (mlt: mutations) per second; cost: 1 - live / plain. "
                 "The issue's target at 256x256 on a 2-core CPU: at least 2 frames/s, a cost of at most 10%.")
    return "\n".join(lines)
