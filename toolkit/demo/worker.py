"""The renderer that runs apart from the page: a thread that renders the chosen techniques a
short pass each in turn, and after each pass publishes what the page shows (a Frame per
technique) in a Snapshot that the page picks up when it next looks.

The page and the renderer never wait for each other: the page only reads the latest snapshot
(a reference swapped under a lock), and hands its changes over as requests that the thread
takes between two passes (so a change acts within a pass, about PASS_SECONDS).

Every pass in the process holds RENDER_LOCK: two tabs share the device's one queue and the kernel
objects of its cached programs (toolkit/opencl/program.py sets a kernel's arguments before each
launch), so their passes take turns instead of interleaving.
"""
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from toolkit.measure.reference import reference_at, reference_problem, rmse
from toolkit.opencl.device import describe, get_queue
from toolkit.opencl.device_scene import DeviceScene
from toolkit.opencl.lanes import can_choose
from toolkit.demo.lanes_picture import lanes_picture
from toolkit.demo.progressive import PASS_SECONDS, progressive
from toolkit.demo.settings import Settings, checked
from toolkit.demo.tone_map import to_rgba

RENDER_LOCK = threading.Lock()
KEPT_MEANS = 600      # points of the image-mean history kept per technique (older ones thinned)


@dataclass
class Frame:
    """One technique as the page shows it after a pass."""
    technique: str
    rgba: np.ndarray             # (H, W, 4) uint8, tone-mapped
    spp: float                   # samples (mlt: mutations) per pixel so far
    samples_per_second: float    # over this technique's own rendering time
    seconds: float               # its rendering time so far
    rmse: float                  # against the scene's reference, or None
    mean: float                  # the image's mean (linear, over pixels and RGB)
    efficiency: dict             # SIMD efficiency per phase so far
    lanes: np.ndarray            # the lanes picture (lanes_picture.py), RGBA
    means: list                  # [(seconds, mean)] so far: the startup-bias plot
    number: int                  # passes so far: the page redraws when it changes
    samples: int = 0             # samples (mlt: mutations) so far
    published: float = 0.0       # time.monotonic() when the frame was made (bench.py's clock)


@dataclass
class Snapshot:
    """What the page reads: the frames, and the state around them."""
    settings: Settings
    frames: dict = field(default_factory=dict)     # technique -> Frame
    status: str = "starting"                       # one line: building, rendering, paused, ...
    error: str = None                              # the last error, shown in the page
    reference_mean: float = None
    reference_note: str = None                     # why there is no RMSE, if there is none
    warp_width: int = None
    device: str = None
    lanes_choosable: bool = False
    version: int = 0


class RenderWorker:
    """Renders `settings` (Settings) from the scenes of `scenes` (SceneChoices) on `device` in a
    thread of its own: start(), then change(...), pause(...), reset(), stop()."""

    def __init__(self, scenes, settings=Settings(), device=None, pass_seconds=PASS_SECONDS):
        self.scenes, self.device, self.pass_seconds = scenes, device, pass_seconds
        self._requested = checked(settings)
        self._snapshot = Snapshot(settings=self._requested)
        self._lock = threading.Lock()          # guards _snapshot and _requested
        self._wake = threading.Event()          # a request arrived, or stop
        self._stop = threading.Event()
        self._paused = False
        self._rebuild = True
        self._thread = threading.Thread(target=self._run, name="demo-renderer", daemon=True)

    # --- what the page calls (any thread) ------------------------------------------------------

    def start(self):
        """Start the thread (once; a stopped worker stays stopped)."""
        if self._thread.ident is None:
            self._thread.start()
        return self

    def snapshot(self):
        with self._lock:
            return self._snapshot

    def change(self, **changes):
        """New settings (checked now: an InputError for a bad value); the thread rebuilds at its next turn."""
        if "scene" in changes:
            self.scenes.path(changes["scene"])      # only a key of the allowed scenes, never a path
        with self._lock:
            self._requested = self._requested.changed(**changes)
            self._rebuild = True
        self._wake.set()

    def reset(self):
        """Start the same settings again from no samples."""
        with self._lock:
            self._rebuild = True
        self._wake.set()

    def pause(self, paused=True):
        self._paused = bool(paused)
        self._publish(status="paused" if paused else "rendering")
        self._wake.set()

    def stop(self, timeout=10.0):
        """Stop the thread after its current pass; True if it ended within `timeout` seconds."""
        self._stop.set()
        self._wake.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout)
        return not self._thread.is_alive()

    @property
    def running(self):
        return self._thread.is_alive()

    # --- the thread ----------------------------------------------------------------------------

    def _run(self):
        renderers, turn = [], 0
        while not self._stop.is_set():
            with self._lock:
                rebuild, settings, self._rebuild = self._rebuild, self._requested, False
            if rebuild:
                renderers, turn = self._build(settings), 0
            if self._paused or not renderers:
                self._wake.wait(0.2)
                self._wake.clear()
                continue
            renderer = renderers[turn % len(renderers)]
            turn += 1
            try:
                with RENDER_LOCK:
                    renderer.advance()
                self._publish_frame(renderer)
            except Exception as error:           # shown in the page; the server goes on
                renderers = []
                self._publish(error=f"{renderer.name}: {one_line(error)}", status="stopped by an error")

    def _build(self, settings):
        """The renderers of `settings`, built (kernels compiled or found in the cache); [] after an error."""
        self._publish(settings=settings, frames={}, status="building the kernels", error=None)
        try:
            with RENDER_LOCK:
                scene = self.scenes.load(settings.scene)
                queue = get_queue(self.device, settings.lanes)
                device_scene = DeviceScene(queue, scene)
                width, height = settings.resolution
                renderers = [progressive(queue, device_scene, t, width, height, settings.seed, self.pass_seconds)
                             for t in settings.techniques]
        except Exception as error:
            self._publish(error=one_line(error), status="not rendering")
            return []
        self._reference, _ = reference_at(scene, width, height)
        self._means = {r.name: [] for r in renderers}
        self._publish(status="paused" if self._paused else "rendering",
                      reference_mean=None if self._reference is None else float(self._reference.mean()),
                      reference_note=None if self._reference is not None else
                      (reference_problem(scene, width, height) or "this scene has no reference image"),
                      warp_width=renderers[0].tech.warp_width, device=describe(queue.device),
                      lanes_choosable=can_choose(queue.device))
        return renderers

    def _publish_frame(self, r):
        image = r.image()
        mean = float(image.mean())
        means = self._means[r.name]
        means.append((r.seconds, mean))
        if len(means) > KEPT_MEANS:
            del means[1::2]                      # thin the old points: the plot keeps its whole time span
        sampler = r.tech.recorder.simd
        frame = Frame(technique=r.name, rgba=to_rgba(image), spp=r.spp,
                      samples_per_second=r.samples / r.seconds if r.seconds else 0.0, seconds=r.seconds,
                      rmse=None if self._reference is None else rmse(image, self._reference), mean=mean,
                      efficiency=r.efficiency(),
                      lanes=lanes_picture(sampler.rows, sampler.warp_width, sampler.warps),
                      means=list(means),
                      number=self.snapshot().frames.get(r.name, _NO_FRAME).number + 1,
                      samples=r.samples, published=time.monotonic())
        with self._lock:
            frames = dict(self._snapshot.frames, **{r.name: frame})
            self._snapshot = _replaced(self._snapshot, frames=frames)

    def _publish(self, **changes):
        with self._lock:
            self._snapshot = _replaced(self._snapshot, **changes)


def _replaced(snapshot, **changes):
    values = dict(vars(snapshot), **changes)
    values["version"] = snapshot.version + 1
    return Snapshot(**values)


class _NoFrame:
    number = 0


_NO_FRAME = _NoFrame()


def one_line(error):
    """An error as one line for the page (kernel build logs keep only their first line)."""
    text = str(error).strip().splitlines()
    return " ".join((text[0] if text else type(error).__name__).split())[:400]
