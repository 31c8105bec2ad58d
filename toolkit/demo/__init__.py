"""The talk's demo, live: the techniques rendering side by side, their SIMD efficiency beside the
talk's figures, the lanes of a few warps step by step, and Metropolis's startup bias shrinking.

`python -m toolkit demo` serves it as a local web page (toolkit/cli/demo.py, server.py);
`live_view(...)` shows the same view in a notebook. The files, each with one purpose:

    progressive.py    a technique rendering one short pass at a time into one image
    worker.py         the thread that renders apart from the page and publishes snapshots
    settings.py       what the viewer chooses, checked (the browser's input is untrusted)
    scenes.py         the scenes the page may open: the bundled ones and the command line's
    lanes_picture.py  which lanes of a few warps are busy at each step, as a picture
    tone_map.py       linear radiance to the browser's 8-bit RGBA
    efficiency.py     SIMD efficiency per phase beside the talk's figures
    view.py           the page's layout and its redraws (Panel and Bokeh)
    still.py          a still of the view where nobody watches it live
    server.py         the web server: one view per tab, and clean stops
    bench.py          frames per second, and the samples/s the live view costs

The view needs Panel (`pip install ".[demo]"`); the rest needs only the toolkit.
"""

from toolkit.core.config import config

__all__ = ["live_view", "require_panel", "DemoUnavailable"]

INSTALL = 'pip install ".[demo]"'
# Where no one watches the notebook (the docs build, the test suite) live_view renders a few
# frames and shows a still, instead of a live widget that needs a browser and a kernel
# (TOOLKIT_NOTEBOOK_HEADLESS=1: toolkit/core/config.py).
HEADLESS_FRAMES = 3


class DemoUnavailable(ImportError):
    """The demo's library (Panel) is not installed; the message names the install command."""


def require_panel():
    """Import Panel, or raise DemoUnavailable saying how to install it."""
    try:
        import panel
    except ImportError as error:
        raise DemoUnavailable(f"the live demo needs Panel, which is not installed ({error}): {INSTALL}") from None
    return panel


def live_view(scene=None, techniques=None, resolution=(128, 128), device=None, lanes=None, seed=0, frames=None):
    """The demo's view in a notebook: display the DemoView this returns (a cell's last line).

    `scene`: a scene folder or a bundled scene's name (default cornell_box); `techniques`: one
    to three names (default pt_naive, pt_inplace_regen, pt_compact_regen), side by side on the
    same samples. It renders live in Jupyter, with the same controls as the web page, until you
    press Pause. With `frames` (or where no one watches: TOOLKIT_NOTEBOOK_HEADLESS=1, as in the
    docs' build and the test suite, 3 frames) it renders that many frames of every technique,
    stops, and shows a still of the last."""
    pn = require_panel()
    from toolkit.demo.scenes import SceneChoices
    from toolkit.demo.settings import DEFAULT_TECHNIQUES, Settings
    from toolkit.demo.view import DemoView
    scenes = SceneChoices(None if scene is None else str(scene))
    settings = Settings(techniques=tuple(techniques or DEFAULT_TECHNIQUES), scene=scenes.first,
                        resolution=tuple(resolution), lanes=lanes, seed=seed).changed()
    if frames is None and config().notebook_headless:
        frames = HEADLESS_FRAMES
    if frames is not None:
        view = DemoView(scenes, settings, device)
        view.run_frames(frames)
        return view
    pn.extension()
    return DemoView(scenes, settings, device, notebook=True).start()
