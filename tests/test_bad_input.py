"""Bad input never crashes, never silently gives a wrong image, never destroys a file (issue 8).

`test_cli_outcome` holds cases of each class of the issue, run as a learner would (the CLI in
a subprocess), and asserts the outcome exactly: the exit code (2 for bad input; a signal would
show as a negative code), a message naming the problem, no traceback, and the old output
files unchanged when the run fails. The other tests hold what a CLI run cannot show cheaply:
every technique means the same by every setting, scenes at the scale limits render like the
unscaled box, and scenes/FORMAT.md states every limit the loader enforces.
"""
import json
import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pytest

import toolkit

from conftest import film_error_techniques
from toolkit.core.validate import LIMITS, limit_text

ROOT = Path(__file__).resolve().parent.parent
CORNELL = ROOT / "scenes" / "cornell_box"
RENDER = ["render", "--spp", "1", "--resolution", "8x8", "--no-progress"]


def edit_json(folder, change):
    data = json.loads((folder / "scene.json").read_text())
    change(data)
    (folder / "scene.json").write_text(json.dumps(data))


def set_in(*path_and_value):
    *path, key, value = path_and_value

    def change(data):
        for p in path:
            data = data[p]
        data[key] = value
    return change


def all_glossy(alpha):
    def change(data):
        for m in data["materials"].values():
            m.update(type="glossy", alpha=alpha)
    return change


def scale_scene(folder, factor):
    """Scale every mesh and the camera of the scene in `folder` by `factor`."""
    for obj in (folder / "meshes").glob("*.obj"):
        lines = [" ".join(["v", *(repr(float(x) * factor) for x in l.split()[1:4])]) if l.startswith("v ") else l
                 for l in obj.read_text().splitlines()]
        obj.write_text("\n".join(lines) + "\n")
    edit_json(folder, lambda d: d["camera"].update(origin=[x * factor for x in d["camera"]["origin"]],
                                                   target=[x * factor for x in d["camera"]["target"]]))


@dataclass
class Case:
    cls: int                     # the class (1..8)
    args: list                   # CLI arguments; "{box}" and "{out}" are filled in
    code: int                    # expected exit code
    says: list                   # fragments of the output (for code 2: of the one "error:" line)
    setup: object = None         # setup(box, tmp_path) before the run
    launch: str = ""             # Python run before the CLI in the subprocess (simulated conditions)
    reference: bool = False      # copy the reference images into the box
    never: list = field(default_factory=list)   # fragments that must not appear


def make_fifo(box, tmp):
    os.mkfifo(box / "meshes" / "pipe.obj")
    edit_json(box, set_in("shapes", 0, "mesh", "meshes/pipe.obj"))


def nested_json(box, tmp):
    (box / "scene.json").write_text("[" * 100_000 + "]" * 100_000)


def truncate_reference(box, tmp):
    data = (box / "reference.exr").read_bytes()
    (box / "reference.exr").write_bytes(data[: len(data) // 2])


# Simulated conditions, set inside the CLI's process just before it writes an image or builds a BVH.
DISK_FULL = """
import resource, toolkit.core.images as im
real = im._write_temporary
def full(*a):   # like a full disk: any file write past 64 bytes fails (EFBIG; SIGXFSZ is ignored by Python)
    resource.setrlimit(resource.RLIMIT_FSIZE, (64, resource.RLIM_INFINITY))
    return real(*a)
im._write_temporary = full
"""
BIG_MESH = ("import toolkit.core.bvh as b; b.PROGRESS_FROM = b.COMPILED_FROM = 1   "
            "# every build counts as big")

CASES = {
    # 1. memory corruption: BDPT at max_depth 0 wrote past its vertex memory (see also test_buffer_guard.py)
    "1-bdpt-max-depth-0": Case(1, [*RENDER, "{box}", "--technique", "bdpt_naive_connect", "--out", "{out}"], 0,
                               ["image mean (linear RGB) [0.0, 0.0, 0.0]", "dropped samples 0"],
                               setup=lambda box, tmp: edit_json(box, set_in("integrator", "max_depth", 0))),
    # 2. techniques disagreed: with regeneration, max_depth 0 rendered as 1 (see test_every_setting_means_the_same)
    "2-regen-max-depth-0": Case(2, [*RENDER, "{box}", "--technique", "pt_compact_regen", "--out", "{out}"], 0,
                                ["image mean (linear RGB) [0.0, 0.0, 0.0]"],
                                setup=lambda box, tmp: edit_json(box, set_in("integrator", "max_depth", 0))),
    # 3. output files
    "3-out-jpg": Case(3, [*RENDER, "--out", "{tmp}/old.jpg"], 2, ["--out", "old.jpg", "unsupported image type '.jpg'"]),
    "3-out-folder": Case(3, [*RENDER, "--out", "{tmp}/folder.exr"], 2, ["folder.exr", "is a folder"],
                         setup=lambda box, tmp: (tmp / "folder.exr").mkdir()),
    "3-out-proc": Case(3, [*RENDER, "--out", "/proc/x.exr"], 2, ["/proc/x.exr", "cannot write there"]),
    "3-out-disk-full": Case(3, [*RENDER, "--out", "{out}"], 2, ["old.exr", "cannot write the image"], launch=DISK_FULL),
    "3-out-png": Case(3, [*RENDER, "--out", "{tmp}/new.png"], 0, ["wrote {tmp}/new.png\n"], never=[" and "]),
    # 4. silently wrong images
    "4-glossy-alpha-1e-4": Case(4, ["render", "--resolution", "16x16", "--technique", "bdpt_parallel_connect",
                                    "--spp", "2", "--no-progress", "{box}", "--out", "{out}"], 0, ["dropped samples 0"],
                                setup=lambda box, tmp: edit_json(box, all_glossy(1e-4))),
    "4-emission-too-big": Case(4, [*RENDER, "{box}"], 2, ["shapes[7].emission component 1e+39 is outside 1e-10 .. 1e+10"],
                               setup=lambda box, tmp: edit_json(box, set_in("shapes", 7, "emission", [1e39, 1, 1]))),
    "4-emission-underflows": Case(4, [*RENDER, "{box}"], 2, ["shapes[7].emission component 1e-46 is outside"],
                                  setup=lambda box, tmp: edit_json(box, set_in("shapes", 7, "emission", [1e-46] * 3))),
    "4-scale-1e13": Case(4, [*RENDER, "{box}"], 2, ["scene extent", "is outside 1e-06 .. 1e+06"],
                         setup=lambda box, tmp: scale_scene(box, 1e13)),
    "4-scale-1e-15": Case(4, [*RENDER, "{box}"], 2, ["scene extent", "is outside 1e-06 .. 1e+06"],
                          setup=lambda box, tmp: scale_scene(box, 1e-15)),
    # 5. typos
    "5-integrator-key": Case(5, [*RENDER, "{box}"], 2, ["unknown key 'maxdepth'", "did you mean 'max_depth'?"],
                             setup=lambda box, tmp: edit_json(box, set_in("integrator", "maxdepth", 3))),
    "5-material-key": Case(5, [*RENDER, "{box}"], 2, ["unknown key 'roughnes'", "did you mean 'alpha'?"],
                           setup=lambda box, tmp: edit_json(box, set_in("materials", "white", {
                               "type": "glossy", "reflectance": [0.5, 0.5, 0.5], "alpha": 0.1, "roughnes": 0.1}))),
    "5-top-key": Case(5, [*RENDER, "{box}"], 2, ["unknown key 'integrater'", "did you mean 'integrator'?"],
                      setup=lambda box, tmp: edit_json(box, set_in("integrater", {}))),
    "5-notes-allowed": Case(5, [*RENDER, "{box}", "--out", "{out}"], 0, ["wrote"],
                            setup=lambda box, tmp: edit_json(box, set_in("materials", "white", "notes", "free text"))),
    # 6. tracebacks instead of errors
    "6-seed-negative": Case(6, [*RENDER, "--seed", "-1"], 2, ["seed -1 is outside 0 .. 2^32 - 1"]),
    "6-seed-2**64": Case(6, [*RENDER, "--seed", str(2 ** 64)], 2, [f"seed {2 ** 64} is outside"]),
    "6-spp-huge": Case(6, [*RENDER, "--spp", str(2 ** 40)], 2, ["spp", "is outside 1 .. 2^24"]),
    "6-resolution-huge": Case(6, [*RENDER, "--resolution", "32768x32768"], 2, ["32768x32768 needs about", "GiB"]),
    "6-equal-time-inf": Case(6, ["bench", "--equal-time", "inf"], 2, ["--equal-time must be finite"]),
    "6-mesh-dev-zero": Case(6, [*RENDER, "{box}"], 2, ["shapes[0]", "/dev/zero", "must be inside the scene folder"],
                            setup=lambda box, tmp: edit_json(box, set_in("shapes", 0, "mesh", "/dev/zero"))),
    "6-mesh-fifo": Case(6, [*RENDER, "{box}"], 2, ["shapes[0]", "pipe.obj", "not a regular file"], setup=make_fifo),
    "6-nested-json": Case(6, [*RENDER, "{box}"], 2, ["scene.json", "JSON nesting depth"], setup=nested_json),
    # 7. misleading figures
    "7-non-square": Case(7, ["render", "--spp", "1", "--resolution", "16x8", "--no-progress", "{box}", "--out", "{out}"], 0,
                         ["no RMSE: the reference is 256x256"], reference=True, never=["RMSE against"]),
    "7-truncated-reference": Case(7, [*RENDER, "{box}", "--out", "{out}"], 0,
                                  ["warning: reference cannot be read", "reference.exr"],
                                  reference=True, setup=truncate_reference, never=["RMSE against"]),
    # 8. long silent work: the BVH build shows progress
    "8-bvh-progress": Case(8, [*RENDER, "{box}", "--out", "{out}"], 0, ["BVH build"], launch=BIG_MESH),
}


def test_every_class_has_a_case():
    assert {c.cls for c in CASES.values()} == set(range(1, 9))


@pytest.mark.parametrize("name", list(CASES))
def test_cli_outcome(name, tmp_path):
    case = CASES[name]
    box = tmp_path / "box"
    shutil.copytree(CORNELL, box, ignore=None if case.reference else shutil.ignore_patterns("*.exr"))
    if case.setup:
        case.setup(box, tmp_path)
    out = tmp_path / "old.exr"
    old = {p: p.name.encode() * 100 for p in (out, out.with_suffix(".png"), tmp_path / "old.jpg")}
    for p, data in old.items():
        p.write_bytes(data)
    fill = lambda s: s.replace("{box}", str(box)).replace("{out}", str(out)).replace("{tmp}", str(tmp_path))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    launcher = f"import sys\n{case.launch}\nfrom toolkit.cli import main\nsys.exit(main(sys.argv[1:]))"
    result = subprocess.run([sys.executable, "-c", launcher, *map(fill, case.args)], cwd=tmp_path, env=env,
                            capture_output=True, text=True, timeout=300)
    output = result.stdout + result.stderr
    assert result.returncode == case.code, output       # a signal would be negative
    assert "Traceback" not in output
    if case.code == 2:
        errors = [l for l in result.stderr.splitlines() if l.startswith("error: ")]
        assert len(errors) == 1, result.stderr
        output = errors[0] + "\n"
    for fragment in map(fill, case.says):
        assert fragment in output, output
    for fragment in case.never:
        assert fragment not in output, output
    if case.code != 0:
        for p, data in old.items():
            assert p.read_bytes() == data, f"{p} changed"
        assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []   # no temporary left


# -- 2. every setting means the same to every technique -----------------------------------------

@pytest.mark.parametrize("max_depth, rr_depth", [(0, 5), (1, 5), (2, -1), (-1, 0)])
def test_every_setting_means_the_same(cornell_box, max_depth, rr_depth):
    """The edge values of max_depth (0: black, 1: emitters only) and rr_depth (0: roulette from
    the first bounce, -1: none) in every technique: the whole-image mean of each agrees with
    pt_naive's within 5 combined standard errors per channel (the mean's standard error is
    sqrt(sum of pixel variances) / pixels; 5 sigma keeps false alarms below 1e-5 per comparison)."""
    scene = replace(cornell_box, max_depth=max_depth, rr_depth=rr_depth)
    figures = {}
    for technique in film_error_techniques():
        spp = 8 if technique.startswith("bdpt") else 64
        r = toolkit.render(scene, technique=technique, spp=spp, seed=5, resolution=(8, 8), count_simd=False)
        assert r.stats["nonfinite_samples"] == 0
        n = r.image.shape[0] * r.image.shape[1]
        figures[technique] = (r.image.mean((0, 1)), np.sqrt((r.stderr ** 2).sum((0, 1))) / n)
    base, base_err = figures["pt_naive"]
    for technique, (mean, err) in figures.items():
        if max_depth == 0:
            assert not mean.any(), technique
        else:
            assert np.all(mean > 0), technique
            assert np.all(np.abs(mean - base) <= 5 * np.hypot(err, base_err)), (technique, mean, base)


# -- 4. scenes at the scale limits render like the unscaled box ----------------------------------

@pytest.mark.parametrize("technique", ["pt_naive", "bdpt_parallel_connect"])
def test_scenes_at_the_scale_limits_render_like_the_box(cornell_box, technique):
    """The same seed gives the same random numbers: at the limits of scene.extent the images
    differ from the unscaled box only by float rounding (and a rare path that rounding turns
    elsewhere), so the means agree to 1%."""
    low, high, _ = LIMITS["scene.extent"]
    plain = toolkit.render(cornell_box, technique=technique, spp=4, seed=3, resolution=(8, 8), count_simd=False)
    for extent, inside in ((low, 1 + 1e-9), (high, 1 - 1e-9)):
        scene = cornell_box.transformed(extent / cornell_box.extent * inside)
        r = toolkit.render(scene, technique=technique, spp=4, seed=3, resolution=(8, 8), count_simd=False)
        assert r.stats["nonfinite_samples"] == 0
        np.testing.assert_allclose(r.image.mean((0, 1)), plain.image.mean((0, 1)), rtol=0.01)


# -- the limits: one table (toolkit/core/validate.py), stated in scenes/FORMAT.md ---------------------

SCENE_LIMITS = [n for n in LIMITS if n.split(".")[0] in ("camera", "material", "shape", "integrator", "scene", "mesh",
                                                         "technique", "mlt")]   # and the technique options FORMAT.md states


def test_format_md_states_every_limit_the_loader_enforces():
    """Each scene limit has a row `| name | low .. high | ... |` in FORMAT.md's Limits table,
    with the loader's values, and the table has no row the loader does not know."""
    text = (ROOT / "scenes" / "FORMAT.md").read_text()
    rows = dict(re.findall(r"^\| `([\w.]+)` \| ([^|]+?) \|", text, re.M))
    assert set(rows) == set(SCENE_LIMITS)
    for name in SCENE_LIMITS:
        assert rows[name] == limit_text(name), name


def test_limits_are_what_the_loader_enforces(tmp_path):
    """Each numeric scene.json limit: the value at the limit loads, one just outside fails and
    names the limit (the table is what the loader uses, not a copy)."""
    from toolkit.core.scene import SceneError, load_scene
    box = tmp_path / "box"
    shutil.copytree(CORNELL, box, ignore=shutil.ignore_patterns("*.exr"))
    original = (box / "scene.json").read_text()
    where = {"camera.width": ("camera", "width"), "camera.height": ("camera", "height"),
             "camera.fov_deg": ("camera", "fov_deg"), "integrator.max_depth": ("integrator", "max_depth"),
             "integrator.rr_depth": ("integrator", "rr_depth")}
    for name, path in where.items():
        low, high, _ = LIMITS[name]
        for value, ok in ((low, True), (high, True), (low - (1 if isinstance(low, int) else low * 1e-3), False),
                          (high + (1 if isinstance(high, int) else 1e-3), False)):
            (box / "scene.json").write_text(original)
            edit_json(box, lambda d: d.setdefault(path[0], {}).__setitem__(path[1], value))
            if name == "integrator.rr_depth":     # without roulette, max_depth must be set
                edit_json(box, set_in("integrator", "max_depth", 5))
            if ok:
                load_scene(box)
            else:
                with pytest.raises(SceneError, match=re.escape(limit_text(name))):
                    load_scene(box)
