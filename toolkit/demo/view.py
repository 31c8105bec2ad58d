"""The live view, one implementation for the web app (toolkit/demo/server.py serves one per tab)
and the notebook widget (toolkit.demo.live_view): Panel lays out Bokeh figures and widgets, and
Panel serves the same object as a page or shows it in Jupyter.

The view never renders. A RenderWorker thread does (worker.py); the view looks at its latest
snapshot every PERIOD_MS and redraws what changed, and hands the controls' changes to it.
"""
import html
import time

import numpy as np
import panel as pn
from bokeh.models import ColumnDataSource
from bokeh.plotting import figure

from toolkit.core.validate import InputError
from toolkit.techniques import TECHNIQUES
from toolkit.demo.efficiency import efficiency_html
from toolkit.demo.lanes_picture import BUSY, BUSY_OTHER, KEPT_STEPS, SAMPLED_WARPS
from toolkit.demo.still import still_png
from toolkit.demo.settings import MOST_TECHNIQUES, RESOLUTIONS, Settings, parse_resolution
from toolkit.demo.tone_map import packed_for_bokeh
from toolkit.demo.worker import RenderWorker

PERIOD_MS = 150          # how often the page looks for a new frame
IMAGE_PIXELS = 300       # on-screen width of each technique's image
COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c")     # one per technique slot, in the mean plot

LANES_NOTE = (
    "Each row is one step of the technique (newest at the bottom), each pixel one lane of {warps} warps of "
    "{w} lanes spread over the step's launch: <span style='color:rgb{extend}'>■</span> busy extending a path, "
    "<span style='color:rgb{generate}'>■</span> busy starting a sample, <span style='color:rgb{connect}'>■</span> "
    "busy connecting (BDPT's naive connect phase: one row per iteration of its loop over a sample's connections; "
    "the parallel one: one row), <span style='color:rgb{other}'>■</span> busy in another step (Metropolis's mutate "
    "and accept), <span style='color:#bbb'>■</span> idle "
    "in a warp that issued the step, blank: the warp had no work and did not issue it; a dark line: the final "
    "drain of a pass (every sample started, the stream emptying), left out here and counted in the table "
    "(Metropolis draws it: each of its iterations is one batch of proposals draining). "
    "From the SIMD counters "
    "(toolkit/core/simd.py): the lanes each counted step had busy, as the kernels reported them.")


def _rgb(colour):
    return tuple(colour[:3])


class DemoView:
    """The page: controls, the images side by side, SIMD efficiency beside the talk's, the lanes
    picture per technique and the image means over time. `scenes`: SceneChoices."""

    def __init__(self, scenes, settings=Settings(), device=None, notebook=False):
        self.scenes, self.notebook = scenes, notebook
        self.worker = RenderWorker(scenes, settings, device)
        self.shown_version, self.shown_numbers, self.slots = -1, {}, {}
        self._callback = None
        self._build_controls(settings)
        self.status = pn.pane.HTML("starting", sizing_mode="stretch_width")
        self.error = pn.pane.Alert("", alert_type="danger", visible=False, sizing_mode="stretch_width")
        self.images = pn.Row()
        self.efficiency = pn.pane.HTML(efficiency_html({}), css_classes=["simd-efficiency"])
        self.lanes = pn.Row()
        self.lanes_note = pn.pane.HTML("", sizing_mode="stretch_width")
        self.means_figure, self.reference_line = self._means_figure()
        self.panel = pn.Column(
            pn.pane.Markdown("## SIMD efficiency, live: the talk's techniques side by side"),
            self.status, self.controls, self.error, self.images, self.efficiency,
            pn.pane.Markdown("### The lanes of a few warps, step by step"), self.lanes, self.lanes_note,
            pn.pane.Markdown("### Image mean over time: Metropolis's startup bias shrinking"),
            pn.pane.Bokeh(self.means_figure), sizing_mode="stretch_width")

    # --- controls ------------------------------------------------------------------------------

    def _build_controls(self, settings):
        resolutions = [f"{w}x{h}" for w, h in RESOLUTIONS]
        chosen = "{}x{}".format(*settings.resolution)
        if chosen not in resolutions:
            resolutions.append(chosen)
        self.techniques = pn.widgets.MultiChoice(label=f"Techniques (1 to {MOST_TECHNIQUES})", options=list(TECHNIQUES),
                                                 value=list(settings.techniques), max_items=MOST_TECHNIQUES, width=420)
        self.scene = pn.widgets.Select(label="Scene", options=self.scenes.names(), value=settings.scene, width=200)
        self.resolution = pn.widgets.Select(label="Resolution", options=resolutions, value=chosen, width=110)
        self.lanes_choice = pn.widgets.RadioButtonGroup(label="SIMD lanes", options=["off", "on"],
                                                        value=settings.lanes or "off", visible=False)
        self.pause = pn.widgets.Toggle(label="Pause", width=80)
        self.reset = pn.widgets.Button(label="Reset", width=80)
        self.techniques.param.watch(lambda e: self.change(techniques=tuple(e.new)), "value")
        self.scene.param.watch(lambda e: self.change(scene=e.new), "value")
        self.resolution.param.watch(lambda e: self.change(resolution=parse_resolution(e.new)), "value")
        self.lanes_choice.param.watch(lambda e: self.change(lanes=e.new), "value")
        self.pause.param.watch(lambda e: self.worker.pause(e.new), "value")
        self.reset.on_click(lambda e: self.worker.reset())
        self.controls = pn.Row(self.techniques, self.scene, self.resolution,
                               pn.Column(pn.pane.HTML("SIMD lanes", visible=False), self.lanes_choice),
                               self.pause, self.reset)

    def change(self, **changes):
        """A control changed: the worker takes it at its next turn; a bad value is shown, not raised."""
        try:
            self.worker.change(**changes)
            self.error.visible = False
        except InputError as error:
            self._show_error(str(error))

    def _show_error(self, text):
        self.error.object = html.escape(text)
        self.error.visible = True

    # --- running -------------------------------------------------------------------------------

    def start(self, period_ms=PERIOD_MS):
        """Start rendering, and redraw every `period_ms` (in the page's own session or notebook)."""
        self.worker.start()
        self._callback = pn.state.add_periodic_callback(self.refresh, period=period_ms)
        return self

    def stop(self, timeout=10.0):
        """Stop redrawing and rendering: the worker ends after its current pass; True if it has
        within `timeout` seconds."""
        if self._callback is not None:
            self._callback.stop()
            self._callback = None
        return self.worker.stop(timeout)

    def refresh(self):
        """Redraw what changed since the last look; returns True if anything did."""
        with pn.io.hold():
            return self._refresh()

    def _refresh(self):
        snap = self.worker.snapshot()
        if snap.version == self.shown_version:
            return False
        self.shown_version = snap.version
        self._show_status(snap)
        if set(self.slots) != set(snap.settings.techniques) or list(self.slots) != list(snap.settings.techniques):
            self._make_slots(snap)
        changed = False
        for name, frame in snap.frames.items():
            if name in self.slots and self.shown_numbers.get(name) != frame.number:
                self.shown_numbers[name] = frame.number
                self._show_frame(self.slots[name], frame, snap)
                changed = True
        if changed:
            self.efficiency.object = efficiency_html({n: f.efficiency for n, f in snap.frames.items()}, snap.warp_width)
            self._show_means(snap)
        if self.notebook:
            pn.io.push_notebook(self.panel)
        return True

    def _show_status(self, snap):
        parts = [f"<b>{html.escape(snap.status)}</b>"]
        if snap.device:
            parts.append(f"on {html.escape(snap.device)}")
        if snap.reference_note:
            parts.append(f"no RMSE: {html.escape(snap.reference_note)}")
        self.status.object = " · ".join(parts)
        self.lanes_choice.visible = snap.lanes_choosable
        self.controls[3][0].visible = snap.lanes_choosable
        if snap.error:
            self._show_error(snap.error)

    # --- the technique slots -------------------------------------------------------------------

    def _make_slots(self, snap):
        """A figure for the image and one for the lanes, per technique of the settings."""
        width, height = snap.settings.resolution
        self.slots, self.shown_numbers = {}, {}
        for i, name in enumerate(snap.settings.techniques):
            self.slots[name] = _Slot(name, width, height, COLOURS[i % len(COLOURS)], snap.warp_width or 32)
        self.images.objects = [s.image_card for s in self.slots.values()]
        self.lanes.objects = [pn.pane.Bokeh(s.lanes_figure) for s in self.slots.values()]
        self.lanes_note.object = LANES_NOTE.format(warps=SAMPLED_WARPS, w=snap.warp_width or 32,
                                                   extend=_rgb(BUSY["extend"]), generate=_rgb(BUSY["generate"]),
                                                   connect=_rgb(BUSY["connect"]), other=_rgb(BUSY_OTHER))
        self.efficiency.object = efficiency_html({})
        lines = {name: dict(x=[], y=[]) for name in self.slots}
        for renderer in list(self.means_figure.renderers):
            if renderer.name and renderer.name.startswith("mean:"):
                self.means_figure.renderers.remove(renderer)
        self.means_figure.legend.items = []
        for slot in self.slots.values():
            slot.means = ColumnDataSource(lines[slot.name], name=f"mean:{slot.name}")
            self.means_figure.line("x", "y", source=slot.means, color=slot.colour, line_width=2,
                                   legend_label=slot.name, name=f"mean:{slot.name}")

    def _show_frame(self, slot, frame, snap):
        slot.image.data = {"image": [packed_for_bokeh(frame.rgba)]}
        slot.lanes.data = {"image": [packed_for_bokeh(frame.lanes)]}
        rate = "mutations" if frame.technique == "mlt" else "samples"
        rmse = f" · RMSE {frame.rmse:.4f}" if frame.rmse is not None else ""
        slot.caption.object = (f"<b>{html.escape(frame.technique)}</b> · {frame.spp:,.1f} spp · "
                               f"{frame.samples_per_second / 1e6:.2f} M {rate}/s{rmse}")
        slot.means.data = {"x": [t for t, _ in frame.means], "y": [m for _, m in frame.means]}

    def _show_means(self, snap):
        longest = max((f.seconds for f in snap.frames.values()), default=1.0)
        if snap.reference_mean is not None:
            self.reference_line.data = {"x": [0.0, max(longest, 1e-3)], "y": [snap.reference_mean] * 2}
        else:
            self.reference_line.data = {"x": [], "y": []}

    def _means_figure(self):
        fig = figure(height=260, sizing_mode="stretch_width", toolbar_location=None, tools="",
                     x_axis_label="seconds of rendering (each technique's own)",
                     y_axis_label="image mean (linear radiance)")
        reference = ColumnDataSource({"x": [], "y": []}, name="reference-mean")
        fig.line("x", "y", source=reference, color="black", line_dash="dashed", legend_label="reference")
        fig.legend.location = "bottom_right"
        return fig, reference

    def run_frames(self, frames, timeout=300.0):
        """Render until every technique has shown `frames` frames, redrawing as the page would,
        then stop: for a notebook that runs headless. Raises RuntimeError with the page's error."""
        self.worker.start()
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.refresh()
            snap = self.worker.snapshot()
            if snap.error:
                self.stop()
                raise RuntimeError(f"the live view stopped: {snap.error}")
            if len(snap.frames) == len(snap.settings.techniques) and \
                    min(f.number for f in snap.frames.values()) >= frames:
                break
            time.sleep(0.02)
        self.stop()
        self.refresh()
        return self.worker.snapshot()

    # --- notebook ------------------------------------------------------------------------------

    def __panel__(self):
        return self.panel

    def _repr_mimebundle_(self, include=None, exclude=None):
        """Live (Panel's widget) while it renders; a still PNG once stopped (run_frames), which a
        page without a kernel (the docs) can show."""
        if self.worker.running or self._callback is not None:
            return self.panel._repr_mimebundle_(include, exclude)
        snap = self.worker.snapshot()
        summary = "; ".join(f"{n}: {f.spp:,.0f} spp" for n, f in snap.frames.items())
        return {"image/png": still_png(snap), "text/plain": f"DemoView (stopped) {summary}"}


class _Slot:
    """One technique's figures: its image with a caption, and its lanes picture."""

    def __init__(self, name, width, height, colour, warp_width):
        self.name, self.colour = name, colour
        shown_height = max(1, round(IMAGE_PIXELS * height / width))
        self.image = ColumnDataSource({"image": [np.zeros((height, width), np.uint32)]}, name=f"image:{name}")
        fig = figure(width=IMAGE_PIXELS, height=shown_height, x_range=(0, width), y_range=(0, height),
                     toolbar_location=None, tools="", min_border=0)
        fig.image_rgba(image="image", x=0, y=0, dw=width, dh=height, source=self.image)
        fig.axis.visible = False
        fig.grid.visible = False
        self.caption = pn.pane.HTML(html.escape(name), width=IMAGE_PIXELS, css_classes=["technique-caption"])
        self.image_card = pn.Column(pn.pane.Bokeh(fig), self.caption)
        lanes_width = SAMPLED_WARPS * (warp_width + 1) - 1
        self.lanes = ColumnDataSource({"image": [np.zeros((KEPT_STEPS, lanes_width), np.uint32)]}, name=f"lanes:{name}")
        lanes = figure(width=IMAGE_PIXELS, height=220, x_range=(0, lanes_width), y_range=(0, KEPT_STEPS),
                       toolbar_location=None, tools="", title=name,
                       x_axis_label=f"lanes of {SAMPLED_WARPS} warps (W = {warp_width})",
                       y_axis_label=f"last {KEPT_STEPS} steps")
        lanes.image_rgba(image="image", x=0, y=0, dw=lanes_width, dh=KEPT_STEPS, source=self.lanes)
        lanes.yaxis.major_label_text_font_size = "0pt"
        lanes.grid.visible = False
        self.lanes_figure = lanes
        self.means = None
