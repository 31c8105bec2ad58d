"""The live demo (toolkit/demo/) without a browser: the lanes picture drawn from made-up counters,
the checks of everything the browser or the command line can send, the render thread, and the
server's stops (SIGTERM and Ctrl-C leave no process). tests/test_demo_browser.py uses the page."""
import os
import re
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from toolkit.cli import main
from toolkit.core.images import to_srgb8
from toolkit.core.simd import PhaseCounter
from toolkit.core.validate import InputError
from toolkit.demo import DemoUnavailable, require_panel
from toolkit.demo.efficiency import efficiency_html, talk_figure
from toolkit.demo.lanes_picture import BUSY, BUSY_OTHER, DRAIN_ROW, GAP, IDLE, WarpSampler, lanes_picture
from toolkit.demo.scenes import SceneChoices
from toolkit.demo.settings import Settings, parse_resolution
from toolkit.demo.tone_map import packed_for_bokeh, to_rgba
from toolkit.demo.worker import RenderWorker

ROOT = Path(__file__).resolve().parent.parent


# --- the lanes picture ----------------------------------------------------------------------------

def pixel(picture, row, warp, lane, warp_width):
    """The colour of one lane in one row (warp w's lanes start at column w x (W + 1))."""
    return tuple(picture[row, warp * (warp_width + 1) + lane])


def test_lanes_picture_from_made_up_counters():
    """Two warps of 4 lanes. Step 0 (a mask, in-place regeneration's way): warp 0 full, warp 1 empty.
    Step 1 (a count packed at the stream's start, compaction's way): 5 lanes busy. Then a loop of
    per-lane iterations (pt_naive's way): rows while the sampled warps' longest lane runs."""
    sampler = WarpSampler(warp_width=4, warps=2, kept=8)
    sampler.add_stream_step("generate", np.array([1, 1, 1, 1, 0, 0, 0, 0], bool), iteration=0)
    sampler.add_stream_step("extend", 5, iteration=1)
    sampler.add_loop_iterations("extend", np.array([2, 1, 1, 1, 0, 0, 0, 0]))
    sampler.add_stream_step("shadow", np.ones(8, bool))     # no iteration: in the counters only, no row
    for step in (4, 5):                                      # a pass's final drain: one dark row for both steps
        sampler.add_stream_step("extend", np.array([1, 0, 0, 0, 0, 0, 0, 0], bool), iteration=step, draining=True)
    picture = lanes_picture(sampler.rows, warp_width=4, warps=2, steps=8)

    assert picture.shape == (8, 2 * 5 - 1, 4) and picture.dtype == np.uint8
    # Row 0: every lane of the full warp busy in the phase's colour; the empty warp issued nothing: blank.
    assert all(pixel(picture, 0, 0, lane, 4) == BUSY["generate"] for lane in range(4))
    assert all(pixel(picture, 0, 1, lane, 4) == GAP for lane in range(4))
    # Row 1: 5 packed lanes: warp 0 full, warp 1 issued with one busy lane and three idle ones.
    assert [pixel(picture, 1, 1, lane, 4) for lane in range(4)] == [BUSY["extend"]] + [IDLE] * 3
    # Rows 2 and 3: the loop; at its second iteration only lane 0 is busy, its warp-mates idle.
    assert pixel(picture, 2, 0, 3, 4) == BUSY["extend"]
    assert [pixel(picture, 3, 0, lane, 4) for lane in range(4)] == [BUSY["extend"]] + [IDLE] * 3
    assert pixel(picture, 3, 1, 0, 4) == GAP
    # Row 4: the drain's marker; then no more rows (the shadow step had no iteration). The gap column
    # between the warps stays blank.
    assert all(pixel(picture, 4, warp, lane, 4) == DRAIN_ROW for warp in (0, 1) for lane in range(4))
    assert (picture[5:] == GAP).all() and (picture[:, 4] == GAP).all()
    # The sampler still counts like the PhaseCounter it is.
    counter = PhaseCounter(4)
    counter.add_stream_step("generate", np.array([1, 1, 1, 1, 0, 0, 0, 0], bool), iteration=0)
    counter.add_stream_step("extend", 5, iteration=1)
    counter.add_loop_iterations("extend", np.array([2, 1, 1, 1, 0, 0, 0, 0]))
    counter.add_stream_step("shadow", np.ones(8, bool))
    for step in (4, 5):
        counter.add_stream_step("extend", np.array([1, 0, 0, 0, 0, 0, 0, 0], bool), iteration=step, draining=True)
    assert sampler.efficiency() == counter.efficiency()


def test_lanes_sampled_spread_over_the_launch():
    """Warps spread over a long launch, not its first ones (the image's top row)."""
    sampler = WarpSampler(warp_width=4, warps=2)
    mask = np.zeros(400, bool)
    mask[92:96] = True          # warp 23 of 100: the first of two sampled ones (golden-ratio steps: 23, 61)
    sampler.add_stream_step("extend", mask, iteration=0)
    assert sampler.rows[0][1][:4].all() and not sampler.rows[0][1][4:].any()


def test_lanes_picture_shows_the_naive_connect_loop_with_its_idle_lanes():
    """The naive connect phase (bdpt_naive_connect.py count_connect, SimdRecorder.inner_loop): a row
    per iteration of its loop over each lane's connections, in the connect colour, the lanes of slots
    still walking (0 connections) idle in a warp that issued; within a pass's final drain, no rows."""
    from toolkit.techniques.simd_recorder import SimdRecorder
    recorder = SimdRecorder(warp_width=4)
    recorder.simd = sampler = WarpSampler(warp_width=4, warps=2, kept=8)
    recorder.step("walk", 8, capacity=8)
    connections = np.array([3, 0, 1, 0, 0, 0, 0, 0])       # warp 1: every slot still walking
    recorder.inner_loop("connect", connections)
    picture = lanes_picture(sampler.rows, warp_width=4, warps=2, steps=8)
    assert [phase for phase, _ in sampler.rows] == ["walk", "connect", "connect", "connect"]
    assert [pixel(picture, 1, 0, lane, 4) for lane in range(4)] == [BUSY["connect"], IDLE, BUSY["connect"], IDLE]
    assert [pixel(picture, 2, 0, lane, 4) for lane in range(4)] == [BUSY["connect"]] + [IDLE] * 3
    assert all(pixel(picture, row, 1, lane, 4) == GAP for row in (1, 2, 3) for lane in range(4))
    assert BUSY["connect"] not in (BUSY["walk"], BUSY["generate"], IDLE, GAP, DRAIN_ROW)
    # In the drain: the connect loop is counted, not drawn; its iterations are numbered as the next step.
    recorder.step("walk", 1, capacity=8, draining=True)
    recorder.inner_loop("connect", connections)
    assert [phase for phase, _ in sampler.rows][4:] == ["drain"] and len(sampler.rows) == 5
    assert [it["iteration"] for it in sampler.per_iteration if it["phase"] == "connect"] == [1, 2, 3, 2, 3, 4]
    # The efficiency figures are those of the plain counters (PhaseCounter.add_warp_loops).
    counter = PhaseCounter(4)
    counter.add_warp_loops("connect", np.concatenate([connections, connections]))
    assert sampler.efficiency()["connect"] == counter.efficiency()["connect"] == 4 / 12


def test_lanes_picture_draws_metropolis_drains():
    """Metropolis (drains=True): each iteration is one batch of proposals draining, drawn step by step:
    mutate, walk steps over a shrinking packed stream, connect, accept."""
    sampler = WarpSampler(warp_width=4, warps=2, kept=8, drains=True)
    sampler.add_stream_step("mutate", 8, iteration=0)
    for step, length in enumerate((8, 5)):
        sampler.add_stream_step("walk", length, iteration=step, draining=True)
    sampler.add_stream_step("connect", 6, iteration=2)
    sampler.add_stream_step("accept", 8, iteration=2)
    picture = lanes_picture(sampler.rows, warp_width=4, warps=2, steps=8)
    assert [phase for phase, _ in sampler.rows] == ["mutate", "walk", "walk", "connect", "accept"]
    assert pixel(picture, 0, 0, 0, 4) == BUSY_OTHER and pixel(picture, 4, 1, 3, 4) == BUSY_OTHER
    assert [pixel(picture, 2, 1, lane, 4) for lane in range(4)] == [BUSY["walk"]] + [IDLE] * 3
    assert [pixel(picture, 3, 1, lane, 4) for lane in range(4)] == [BUSY["connect"]] * 2 + [IDLE] * 2
    assert not (picture[:5] == DRAIN_ROW).all(-1).any()


def test_tone_map_and_bokeh_layout():
    image = np.zeros((2, 3, 3))
    image[0, 0] = 1.0             # top-left white
    rgba = to_rgba(image)
    assert rgba.shape == (2, 3, 4) and tuple(rgba[0, 0]) == (255, 255, 255, 255) and tuple(rgba[1, 2]) == (0, 0, 0, 255)
    wide = np.random.default_rng(1).random((16, 16, 3)) ** 3 * 1.2     # dark values, where sRGB is steep
    assert np.abs(to_rgba(wide)[..., :3].astype(int) - to_srgb8(wide).astype(int)).max() <= 1
    packed = packed_for_bokeh(rgba)
    assert packed.shape == (2, 3) and packed.dtype == np.uint32
    assert packed[1, 0] == 0xFFFFFFFF and packed[0, 0] == 0xFF000000   # Bokeh's rows run bottom up


def test_efficiency_table_shows_the_talks_figures():
    assert talk_figure("pt_naive", "extend") == 0.33 and talk_figure("pt_inplace_regen", "generate") == 0.30
    assert talk_figure("bdpt_naive_connect", "connect") == 0.17 and talk_figure("pt_compact_regen", "overall") == 0.99
    text = efficiency_html({"pt_naive": {"extend": 0.41, "overall": 0.40}, "<b>x": {"overall": 1.0}}, 32)
    assert "41.0%" in text and "talk ~33%" in text and "warps of 32" in text
    assert "<b>x" not in text.replace("<b>&lt;b&gt;x</b>", "")      # names are escaped


# --- what the browser and the command line can send -------------------------------------------------

def test_browser_input_names_no_file_outside_the_allowed_scenes(tmp_path):
    scenes = SceneChoices()
    for sent in ("../../etc/passwd", "/etc/passwd", str(ROOT / "scenes" / "cornell_box"), "cornell_box/../..", None, 7):
        with pytest.raises(InputError, match="opens only the bundled scenes"):
            scenes.path(sent)
    assert scenes.path("covered_lamp").name == "covered_lamp"
    worker = RenderWorker(scenes)             # not started: change() checks on the caller's thread
    with pytest.raises(InputError, match="opens only"):
        worker.change(scene="/etc")
    for bad in ({"techniques": ("pt_naive; rm -rf /",)}, {"techniques": ()}, {"techniques": "pt_naive"},
                {"techniques": ("pt_naive",) * 2 + ("pt_inplace_regen", "pt_compact_regen", "mlt")},
                {"resolution": (99999, 1)}, {"resolution": "64"}, {"lanes": "maybe"}, {"seed": -1}):
        with pytest.raises(InputError):
            Settings().changed(**bad)
    assert Settings().changed(techniques=["pt_naive", "pt_naive"]).techniques == ("pt_naive",)
    with pytest.raises(InputError, match="WIDTHxHEIGHT"):
        parse_resolution("<script>")


def test_page_shows_an_error_for_a_bad_choice():
    pytest.importorskip("panel", reason='the demo needs Panel: pip install ".[demo]"')
    from toolkit.demo.view import DemoView
    view = DemoView(SceneChoices())                        # not started: no thread
    view.change(scene="../../etc/passwd")
    assert view.error.visible and "opens only the bundled scenes" in view.error.object
    view.change(resolution=(64, 64))
    assert not view.error.visible


def run_main(capsys, *args):
    code = main(["demo", "--no-browser", *args])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return code, err


def test_bad_scene_folder_is_one_line_and_exit_2(tmp_path, capsys):
    code, err = run_main(capsys, str(tmp_path / "nowhere"))
    assert code == 2 and re.search(r"error: .*nowhere: no such scene folder", err), err
    (tmp_path / "broken").mkdir()
    (tmp_path / "broken" / "scene.json").write_text("{ not json")
    code, err = run_main(capsys, str(tmp_path / "broken"))
    assert code == 2 and err.startswith("error: ") and "scene.json" in err, err
    code, err = run_main(capsys, str(tmp_path))         # a folder holding one bad scene
    assert code == 2 and err.startswith("error: ")


def test_bad_resolution_and_device_are_one_line_and_exit_2(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["demo", "--resolution", "0x5"])
    assert stop.value.code == 2 and "expected WIDTHxHEIGHT" in capsys.readouterr().err
    code, err = run_main(capsys, "--resolution", "4096x4096")
    assert code == 2 and "renders 8x8 to 1024x1024" in err, err
    code, err = run_main(capsys, "--device", "no-such-device-anywhere")
    assert code == 2 and err.startswith("error: "), err


def test_missing_panel_names_the_install_command(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "panel", None)          # as if not installed
    with pytest.raises(DemoUnavailable, match=re.escape('pip install ".[demo]"')):
        require_panel()
    code, err = run_main(capsys)
    assert code == 2 and 'pip install ".[demo]"' in err


# --- the render thread ---------------------------------------------------------------------------------

def test_two_workers_render_side_by_side():
    """Two tabs' threads share the device's queue: both render, neither errs, and the same seeds
    give the same image at the same samples per pixel."""
    settings = Settings(techniques=("pt_naive",), resolution=(16, 16))
    workers = [RenderWorker(SceneChoices(), settings, pass_seconds=0.02).start() for _ in range(2)]
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not all(
                w.snapshot().frames.get("pt_naive") and w.snapshot().frames["pt_naive"].number >= 3 for w in workers):
            assert not any(w.snapshot().error for w in workers), [w.snapshot().error for w in workers]
            time.sleep(0.05)
        frames = [w.snapshot().frames["pt_naive"] for w in workers]
        assert all(f.number >= 3 and f.spp > 0 and f.rmse is not None for f in frames)
        workers[0].pause()
        time.sleep(0.3)
        paused_at = workers[0].snapshot().frames["pt_naive"].number
        time.sleep(0.5)
        assert workers[0].snapshot().frames["pt_naive"].number == paused_at and workers[0].snapshot().status == "paused"
    finally:
        assert all(w.stop() for w in workers)


def test_headless_live_view_renders_frames_then_shows_a_still():
    pytest.importorskip("panel", reason='the demo needs Panel: pip install ".[demo]"')
    from toolkit.demo import live_view
    view = live_view(techniques=["pt_naive", "pt_compact_regen"], resolution=(16, 16), frames=2)
    snap = view.worker.snapshot()
    assert not view.worker.running and min(f.number for f in snap.frames.values()) >= 2
    bundle = view._repr_mimebundle_()
    assert bundle["image/png"][:8] == b"\x89PNG\r\n\x1a\n"
    assert snap.frames["pt_compact_regen"].efficiency["overall"] > 0.9


# --- the server's stops -------------------------------------------------------------------------------

def descendants_and_group(pid):
    """Processes left in the server's process group (it was started in a session of its own)."""
    left = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pid and fields[0] != "Z":      # fields[2]: the process group
            left.append(int(stat.parent.name))
    return left


@pytest.mark.skipif(sys.platform != "linux", reason="reads /proc")
@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "Ctrl-C"])
def test_signal_stops_everything_and_leaves_no_process(stop):
    pytest.importorskip("panel", reason='the demo needs Panel: pip install ".[demo]"')
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = subprocess.Popen([sys.executable, "-m", "toolkit", "demo", "--no-browser", "--port", str(port),
                               "--resolution", "32x32", "--techniques", "pt_naive"],
                              cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                              start_new_session=True, env=dict(os.environ, PYTHONUNBUFFERED="1"))
    try:
        line = server.stdout.readline()
        assert "serving the demo at http://127.0.0.1:" in line, line + server.stdout.read()
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=30) as page:   # a tab: its thread starts
            assert b"SIMD efficiency, live" in page.read()
        time.sleep(1.0)                                     # the thread is rendering now
        server.send_signal(stop)
        assert server.wait(timeout=30) == 0, server.stdout.read()
    finally:
        if server.poll() is None:
            os.killpg(server.pid, signal.SIGKILL)
            server.wait()
    assert descendants_and_group(server.pid) == []
    assert "Traceback" not in server.stdout.read()
