"""Long runs check their outputs first, and Dask workers see the scene the user sees (issue 24):
--out before the study, absolute scene paths and a scene cache keyed by content, knob values
by type, non-UTF-8 paths and temporary files, the OBJ reader's limits while it reads, render's
memory estimate before any camera allocation, and a --strategies folder without stale images.
Each refusal is checked to come before any render (the render is replaced by a failure)."""
import dataclasses
import json
import os
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from toolkit.cli import main
from toolkit.core import images, validate
from toolkit.core.obj import read_obj
from toolkit.core.scene import SceneError, load_scene
from toolkit.core.validate import InputError, LIMITS
from toolkit.measure import strategies
from toolkit.measure.study import runs, workers
from toolkit.measure.study.knobs import Repetition, Run, make_runs, parse_knob
from toolkit.peers import mitsuba
from toolkit.techniques.bdpt_evaluator import walk_defines
from toolkit.techniques.strategy_images import StrategyImages
from toolkit.verify import crosscheck

ROOT = Path(__file__).resolve().parent.parent
CORNELL = ROOT / "scenes" / "cornell_box"
NOT_UTF8 = os.fsdecode(b"caf\xe9")     # Latin-1 bytes: a valid file name, not UTF-8


def no_work(*args, **kwargs):
    raise AssertionError("work started before the inputs were checked")


@pytest.fixture
def box(tmp_path):
    folder = tmp_path / "box"
    shutil.copytree(CORNELL, folder)
    return folder


def test_study_checks_out_before_it_renders(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(runs, "map_jobs", no_work)
    (tmp_path / "file").write_text("")
    for out, problem in ((tmp_path / "file" / "study", "cannot write there"), (tmp_path / "file", "is a file"),
                         (tmp_path / NOT_UTF8, "not valid UTF-8")):
        assert main(["study", "--techniques", "pt_naive", "--spp-budgets", "1", "--repeats", "1",
                     "--out", str(out), "--no-progress"]) == 2
        assert problem in capsys.readouterr().err


def test_study_ships_an_absolute_path_and_the_scenes_digest(monkeypatch):
    shipped = []

    def capture(function, items, *args):
        shipped.extend(items)
        raise StopIteration
    monkeypatch.setattr(runs, "map_jobs", capture)
    monkeypatch.chdir(ROOT)
    with pytest.raises(StopIteration):
        runs.study("scenes/cornell_box", ["pt_naive"], spp_budgets=[1], repeats=1, resolution=(8, 8))
    job = shipped[0][0]
    assert job.scene == str(CORNELL.resolve() / "scene.json")
    assert job.scene_digest == workers.scene_digest(load_scene(CORNELL))


def test_an_edited_scene_is_read_again(box):
    """The cache of scenes in a process (a Dask worker's, a notebook's) is keyed by the scene's
    content: a second study after an edit renders the edited scene (it rendered the first)."""
    def job(digest):
        return Repetition(str(box / "scene.json"), Run("pt_naive", "pt_naive", resolution=(8, 8)), 2, 7,
                          scene_digest=digest)
    first = workers.run_repetition(job(workers.scene_digest(load_scene(box))))["image"]
    data = json.loads((box / "scene.json").read_text())
    for material in data["materials"].values():
        if "reflectance" in material:
            material["reflectance"] = [0.1, 0.1, 0.1]
    (box / "scene.json").write_text(json.dumps(data))
    edited = workers.scene_digest(load_scene(box))
    second = workers.run_repetition(job(edited))["image"]
    assert second.mean() < 0.8 * first.mean()       # darker walls: the edit is seen
    assert np.array_equal(workers.run_repetition(job(edited))["image"], second)
    with pytest.raises(InputError, match="differs from the one the study started with"):
        workers.run_repetition(job("the digest of the scene before the edit"))


def test_knob_values_are_parsed_with_the_options_own_type(tmp_path, monkeypatch, capsys):
    runs_ = make_runs(["bdpt_parallel_connect"], parse_knob("coalesced_scatter=false,true"), (8, 8))
    assert [r.options for r in runs_] == [(("coalesced_scatter", False),), (("coalesced_scatter", True),)]
    assert parse_knob("combine=false,1") == ("combine", [False, True])
    make_runs(["mlt"], parse_knob("combine=false"), (8, 8))             # refused before: the string 'false'
    assert parse_knob("regenerate_fraction=0.5") == ("regenerate_fraction", [0.5])
    assert parse_knob("clamp=none,2") == ("clamp", [None, 2.0]) and parse_knob("chains=none,8")[1] == [None, 8]
    with pytest.raises(ValueError, match="coalesced_scatter must be true or false"):
        walk_defines(load_scene(CORNELL), 8, "false")                    # from Python: refused too
    monkeypatch.setattr(runs, "map_jobs", no_work)
    for knob, problem in (("regenerate_fraction=abc", "takes a number, got 'abc'"),
                          ("coalesced_scatter=yes", "takes true or false"),
                          ("max_depth=2.5", "takes a whole number"), ("large_step=none", "has no 'none'")):
        technique = "mlt" if "large_step" in knob else "bdpt_parallel_connect"
        assert main(["study", "--techniques", technique, "--knob", knob, "--spp-budgets", "1", "--no-progress",
                     "--out", str(tmp_path)]) == 2
        err = capsys.readouterr().err
        assert problem in err and "Traceback" not in err, err


def test_paths_that_are_not_utf8_are_refused_before_the_render(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr("toolkit.cli.render.render", no_work)
    assert main(["render", "--out", str(tmp_path / f"{NOT_UTF8}.exr"), "--no-progress"]) == 2
    assert "not valid UTF-8" in capsys.readouterr().err and os.listdir(tmp_path) == []
    shutil.copytree(CORNELL, tmp_path / NOT_UTF8)
    with pytest.raises(SceneError, match="not valid UTF-8"):
        load_scene(tmp_path / NOT_UTF8)
    with pytest.raises(OSError, match="not valid UTF-8"):
        images.read_exr(tmp_path / NOT_UTF8 / "reference.exr")


def test_a_failed_image_write_leaves_no_temporary_file(tmp_path, monkeypatch):
    def refuses(name):
        raise TypeError("create(): incompatible function arguments")    # what OpenImageIO raised
    fake = SimpleNamespace(**{k: getattr(images.oiio, k) for k in ("FLOAT", "UINT8", "ImageSpec")},
                           ImageOutput=SimpleNamespace(create=refuses))
    monkeypatch.setattr(images, "oiio", fake)
    with pytest.raises(TypeError):
        images.write_image(tmp_path / "image.exr", np.zeros((2, 2, 3), np.float32))
    assert os.listdir(tmp_path) == []


def test_the_obj_reader_stops_at_the_limits_while_it_reads(tmp_path, monkeypatch):
    mesh = tmp_path / "mesh.obj"
    mesh.write_text("".join(f"v {i} {i * i} 1\n" for i in range(100)) +
                    "".join(f"f 1 {i} {i + 1}\n" for i in range(2, 100)))
    assert read_obj(mesh)[1].shape == (98, 3)
    monkeypatch.setitem(LIMITS, "scene.triangles", (1, 10, "test"))
    with pytest.raises(InputError, match=r"mesh.obj:111: the scene's triangle count .* stopped here"):
        read_obj(mesh)                      # the 11th face, on line 100 + 11: not after the last
    with pytest.raises(InputError, match=r"mesh.obj:101: .* is outside 1 .. 10"):
        read_obj(mesh, earlier_triangles=10)                    # the scene's other meshes count
    monkeypatch.setitem(LIMITS, "scene.vertices", (1, 20, "test"))
    with pytest.raises(InputError, match=r"mesh.obj:21: the scene's vertex count"):
        read_obj(mesh)
    mesh.write_text("v 0 0 0\n" + "#" * (LIMITS["mesh.line_length"][1] + 1) + "\n")
    with pytest.raises(InputError, match=r"mesh.obj:2: line length"):
        read_obj(mesh)


def test_crosscheck_and_the_embree_bench_use_renders_memory_estimate(cornell_box, monkeypatch):
    """A 32768x32768 camera (allowed by the camera limits) is refused before anything is
    allocated for it: it tried to allocate 8 GiB of rays."""
    monkeypatch.setattr(validate, "physical_memory", lambda: 16 << 30)
    monkeypatch.setattr(crosscheck, "DeviceScene", no_work)
    monkeypatch.setattr(mitsuba, "DeviceScene", no_work)
    with pytest.raises(InputError, match="resolution 32768x32768 needs about"):
        crosscheck.compare_with_embree(cornell_box, resolution=(32768, 32768))
    huge = dataclasses.replace(cornell_box, camera=dataclasses.replace(cornell_box.camera, width=32768, height=32768))
    with pytest.raises(InputError, match="resolution 32768x32768 needs about"):
        mitsuba.embree_rays(huge)


def _strategy_images(max_edges, rng):
    result = StrategyImages(max_edges, 4, 4)
    result.weighted[:], result.unweighted[:] = rng.random(result.weighted.shape), rng.random(result.weighted.shape)
    result.luminance_sq[:], result.spp = rng.random(result.luminance_sq.shape) + 1, 1
    return result


def test_a_reused_strategies_folder_keeps_only_this_runs_images(tmp_path, monkeypatch, capsys):
    rng, image = np.random.default_rng(3), np.ones((4, 4, 3))
    folder = tmp_path / "strategies"
    strategies.write_strategies(folder, image, _strategy_images(2, rng), "box", "bdpt_parallel_connect")
    assert (folder / "s2_t1_weighted.exr").is_file()            # a path of 2 edges
    report = strategies.write_strategies(folder, image, _strategy_images(1, rng), "box", "bdpt_parallel_connect")
    assert sorted(os.listdir(folder)) == sorted(report["files"] + ["strategies.json"])
    assert not (folder / "s2_t1_weighted.exr").exists()
    assert json.loads((folder / "strategies.json").read_text())["max_edges"] == 1
    (folder / "notes.txt").write_text("mine")          # a folder of other files: refused before the render
    monkeypatch.setattr("toolkit.cli.render.render", no_work)
    assert main(["render", "--technique", "bdpt_parallel_connect", "--strategies", str(folder)]) == 2
    assert "notes.txt, which --strategies did not write" in capsys.readouterr().err
    assert (folder / "notes.txt").read_text() == "mine"
