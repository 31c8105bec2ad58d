"""The demo in a real browser: headless chromium opens `python -m toolkit demo`'s page, sees the
image change at least three times and the SIMD efficiency figures appear, switches the
techniques as a viewer would, finds no console error, and saves a screenshot for the docs
(docs/_build/demo.png, shown on the demo's page: docs/conf.py copies it in). Closing the tab then
stops the server, leaving no process."""
import os
import signal
import socket
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from chromium_page import BROWSER, ChromiumPage
from toolkit.demo.lanes_picture import BUSY, BUSY_OTHER, IDLE, KEPT_STEPS

ROOT = Path(__file__).resolve().parent.parent
SCREENSHOT = ROOT / "docs" / "_build" / "demo.png"

DOCUMENT = "Bokeh.documents[0]"
# A checksum of the pixels that a technique's image has in the page now (null before it exists).
CHECKSUM = """(() => {{
  const source = window.Bokeh && Bokeh.documents.length ? Bokeh.documents[0].get_model_by_name('image:{name}') : null;
  if (!source) return null;
  const pixels = source.data.image[0];
  let sum = 0;
  for (let i = 0; i < pixels.length; i++) sum = (sum + pixels[i] * (i + 1)) % 1000000007;
  return sum;
}})()"""
STATUS = ("window.Bokeh && Bokeh.documents.length ? Array.from(Bokeh.documents[0].all_models)"
          ".filter(m => typeof m.text === 'string' || typeof m.object === 'string')"
          ".map(m => m.text || m.object).join(' | ').slice(0, 2000) : 'no Bokeh document'")
EFFICIENCY = ("Array.from(Bokeh.documents[0].all_models).filter(m => (m.css_classes || [])"
              ".includes('simd-efficiency')).map(m => m.text).join('')")

# The pixels of a technique's lanes picture in the page (Bokeh's packed RGBA, one uint32 each), or null.
LANES = """(() => {{
  const source = window.Bokeh && Bokeh.documents.length ? Bokeh.documents[0].get_model_by_name('lanes:{name}') : null;
  return source ? Array.from(source.data.image[0]) : null;
}})()"""


def lanes_rows(page, name):
    """`name`'s lanes picture as the page has it: (steps, width, 4) RGBA, top row first."""
    pixels = page.evaluate(LANES.format(name=name))
    if pixels is None:
        return None
    packed = np.array(pixels, np.uint32).reshape(KEPT_STEPS, -1)[::-1]     # Bokeh's bottom row first
    return np.ascontiguousarray(packed).view(np.uint8).reshape(*packed.shape, 4)


def cells(picture, colour):
    """Per row, the number of lanes drawn in `colour`."""
    return (picture == np.array(colour, np.uint8)).all(-1).sum(1)


def changes_seen(page, name, wanted, timeout=120):
    """The distinct checksums of `name`'s image, polled until `wanted` changes were seen."""
    seen, deadline = [], time.monotonic() + timeout
    while time.monotonic() < deadline and len(seen) < wanted + 1:
        value = page.evaluate(CHECKSUM.format(name=name))
        if value is not None and (not seen or value != seen[-1]):
            seen.append(value)
        time.sleep(0.05)
    return len(seen) - 1


@pytest.fixture
def demo_server():
    with serve_demo("pt_naive,pt_inplace_regen") as served:
        yield served


@contextmanager
def serve_demo(techniques):
    """`python -m toolkit demo` at 64x64 with `techniques`: (the server, its address), then killed."""
    pytest.importorskip("panel", reason='the demo needs Panel: pip install ".[demo]"')
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = subprocess.Popen([sys.executable, "-m", "toolkit", "demo", "--no-browser", "--port", str(port),
                               "--resolution", "64x64", "--techniques", techniques],
                              cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                              start_new_session=True, env=dict(os.environ, PYTHONUNBUFFERED="1"))
    line = server.stdout.readline()
    assert "serving the demo at" in line, line + server.stdout.read()
    try:
        yield server, f"http://127.0.0.1:{port}/"
    finally:
        if server.poll() is None:
            os.killpg(server.pid, signal.SIGKILL)
            server.wait()


@pytest.mark.skipif(BROWSER is None, reason="no headless browser (chromium) installed: apt-get install chromium")
def test_demo_in_a_browser(demo_server):
    pytest.importorskip("websocket", reason="websocket-client drives the browser: pip install '.[test]'")
    server, url = demo_server
    with ChromiumPage() as page:
        page.open(url)
        seen = changes_seen(page, "pt_naive", 3)
        assert seen >= 3, f"the image changed {seen} times; the page says: {page.evaluate(STATUS)}"
        figures = page.wait_for(f"(() => {{ const t = {EFFICIENCY}; return /pt_inplace_regen/.test(t) && "
                                r"(t.match(/\d+\.\d%/g) || []).length >= 6 ? t : null })()", timeout=30)
        assert "talk ~33%" in figures and "talk ~30%" in figures
        # Switch the techniques as the viewer's choice box does (its model's value, synced to the server).
        page.evaluate(f"Array.from({DOCUMENT}.all_models).find(m => m.type === 'MultiChoice').value = "
                      "['pt_naive', 'pt_inplace_regen', 'pt_compact_regen']")
        assert changes_seen(page, "pt_compact_regen", 2) >= 2, "the added technique's image did not change"
        page.wait_for(f"/pt_compact_regen[\\s\\S]*99\\.\\d%/.test({EFFICIENCY})", timeout=30)
        time.sleep(1.5)           # a few more frames for the screenshot: the lanes pictures fill
        page.screenshot(SCREENSHOT)
        errors = list(page.errors)
    assert SCREENSHOT.stat().st_size > 20_000
    assert not errors, errors
    # The tab is closed: its session ends, then the server, leaving nothing behind.
    assert server.wait(timeout=30) == 0
    output = server.stdout.read()
    assert "the last tab was closed" in output and "Traceback" not in output, output


@pytest.mark.skipif(BROWSER is None, reason="no headless browser (chromium) installed: apt-get install chromium")
def test_two_tabs_at_once(demo_server):
    """Two tabs (two browsers: two sessions, each with its own render thread) both converge; closing
    one leaves the other live, and the server stops only when the second has closed too."""
    pytest.importorskip("websocket", reason="websocket-client drives the browser: pip install '.[test]'")
    server, url = demo_server
    with ChromiumPage(900, 1200) as first, ChromiumPage(900, 1200) as second:
        first.open(url)
        second.open(url)
        for tab in (first, second):
            seen = changes_seen(tab, "pt_naive", 2)
            assert seen >= 2, f"a tab's image changed {seen} times; it says: {tab.evaluate(STATUS)}"
        errors = list(first.errors)
        first.close()
        assert changes_seen(second, "pt_naive", 2) >= 2, "the other tab stopped when the first was closed"
        assert server.poll() is None, "the server stopped while a tab was still open"
        errors += second.errors
    assert not errors, errors
    assert server.wait(timeout=30) == 0
    output = server.stdout.read()
    assert "the last tab was closed" in output and "Traceback" not in output, output


@pytest.mark.skipif(BROWSER is None, reason="no headless browser (chromium) installed: apt-get install chromium")
def test_lanes_pictures_show_each_techniques_lesson():
    """bdpt_naive_connect's picture has connect-phase rows with idle lanes (the slots still walking,
    the sample's loop over its connections ended), and mlt's picture is not empty: its chains' steps."""
    pytest.importorskip("websocket", reason="websocket-client drives the browser: pip install '.[test]'")
    with serve_demo("bdpt_naive_connect,mlt") as (server, url):
        with ChromiumPage() as page:
            page.open(url)
            pictures, deadline = {}, time.monotonic() + 180
            while time.monotonic() < deadline:
                pictures = {name: lanes_rows(page, name) for name in ("bdpt_naive_connect", "mlt")}
                if all(p is not None for p in pictures.values()):
                    connect = pictures["bdpt_naive_connect"]
                    idle_connect_rows = (cells(connect, BUSY["connect"]) > 0) & (cells(connect, IDLE) > 0)
                    mlt = pictures["mlt"]
                    mlt_busy = sum(cells(mlt, c).sum() for c in (BUSY["walk"], BUSY["connect"], BUSY_OTHER))
                    if idle_connect_rows.any() and mlt_busy > 0:
                        break
                time.sleep(0.5)
            else:
                pytest.fail(f"the lanes pictures did not show their lessons; the page says: {page.evaluate(STATUS)}")
            errors = list(page.errors)
        assert not errors, errors
        # both of mlt's kinds of step, the BDPT walk and its Metropolis steps (mutate, accept)
        assert cells(mlt, BUSY["walk"]).sum() > 0 and cells(mlt, BUSY_OTHER).sum() > 0
