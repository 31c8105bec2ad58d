"""The compiled BVH build (toolkit/core/sah_build.py, wide_children.py) against the numpy one
(toolkit/core/bvh.py): the same nodes, triangle order, depth and wide BVH, bit for bit, on the
bundled scenes, on random triangles made to tie (rounded coordinates, coincident centroids) and
on a UV sphere like the million-triangle scene's (scenes/tools/make_million.py)."""
import functools
import importlib.util

import numpy as np
import pytest

from conftest import ROOT, scene_dirs
from toolkit.core import bvh
from toolkit.core.scene import load_scene

spec = importlib.util.spec_from_file_location("make_million", ROOT / "scenes" / "tools" / "make_million.py")
make_million = importlib.util.module_from_spec(spec)
spec.loader.exec_module(make_million)


def rebased(scene):
    """The scene as DeviceScene hands it to the build: float64 vertices, centred, and triangles."""
    lo, hi = scene.vertices.min(0), scene.vertices.max(0)
    return scene.vertices - 0.5 * (lo + hi), scene.triangles


def unshared(tri_vertices):
    """(vertices, triangles) of (M, 3, 3) triangle vertices that share no vertex."""
    return tri_vertices.reshape(-1, 3), np.arange(3 * len(tri_vertices)).reshape(-1, 3)


def random_triangles(seed):
    """Triangles of 1 to 2,000, some rounded to one decimal (equal bins, equal costs), some with
    half of them on one triangle (coincident centroids: the build splits the list in half)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 2000))
    tv = rng.random((n, 3, 3)) * rng.random(3) * 10
    if seed % 3 == 0:
        tv = np.round(tv, 1)
    if seed % 5 == 0:
        tv[: n // 2] = tv[0]
    return unshared(tv)


def sphere_triangles(around=120, rings=60):
    vertices, triangles = make_million.uv_sphere(around, rings)
    tv = vertices[triangles]
    area = np.linalg.norm(np.cross(tv[:, 1] - tv[:, 0], tv[:, 2] - tv[:, 0]), axis=1)
    return vertices, triangles[area > 0]     # the poles' degenerate triangles, as the loader drops them


CASES = {p.name: (lambda p=p: rebased(load_scene(p))) for p in scene_dirs()}
CASES.update({f"random{seed}": (lambda seed=seed: random_triangles(seed)) for seed in range(8)})
CASES["one triangle"] = lambda: unshared(np.random.default_rng(1).random((1, 3, 3)))      # the root is a leaf
CASES["six triangles"] = lambda: unshared(np.random.default_rng(2).random((6, 3, 3)))     # its children are
CASES["sphere 120x60"] = sphere_triangles


def assert_same(a, b):
    for what, x, y in zip(("lo", "hi", "first", "count", "axis", "order", "depth"), a, b):
        assert np.array_equal(np.asarray(x), np.asarray(y)), what


@pytest.mark.parametrize("case", CASES)
def test_compiled_build_gives_numpy_tree(case):
    vertices, triangles = CASES[case]()
    assert_same(bvh._build_numpy(vertices[triangles], 4, 16), bvh._build_compiled(vertices, triangles, 4, 16))


def test_a_build_in_steps_gives_the_same_tree(monkeypatch):
    """The progress bar's steps (PROGRESS_STEP) stop and resume the build: any step gives one tree."""
    sphere = sphere_triangles(60, 30)
    whole = bvh._build_compiled(*sphere, 4, 16)
    monkeypatch.setattr(bvh, "PROGRESS_STEP", 7)
    assert_same(whole, bvh._build_compiled(*sphere, 4, 16))


def test_a_build_that_runs_out_of_room_makes_more(monkeypatch):
    """A state starts with room for some nodes and stack entries and doubles what runs out: from
    room for one of each, the same tree."""
    from toolkit.core import sah_build
    sphere = sphere_triangles(60, 30)
    whole = bvh._build_compiled(*sphere, 4, 16)
    monkeypatch.setattr(sah_build, "NODE_ROOM", 0.0)
    monkeypatch.setattr(sah_build, "STACK_ROOM", 1)
    assert_same(whole, bvh._build_compiled(*sphere, 4, 16))


@functools.lru_cache(maxsize=None)
def tree(case):
    return bvh.build_bvh(*CASES[case]())


@pytest.mark.parametrize("width", [4, 8])
@pytest.mark.parametrize("case", ["random0", "random7", "sphere 120x60"])
def test_compiled_wide_children_are_pythons(case, width, monkeypatch):
    nodes = tree(case).nodes
    leaf = nodes["count"] > 0
    monkeypatch.setattr(bvh, "COMPILED_FROM", 1 << 40)
    python = bvh._wide_children(nodes, leaf, width)
    monkeypatch.setattr(bvh, "COMPILED_FROM", 0)
    compiled = bvh._wide_children(nodes, leaf, width)
    for what, x, y in zip(("kids", "index_of", "depth", "stack"), python, compiled):
        assert np.array_equal(x, y), what
    assert (python[0][:, 1] >= 0).any(), "a wide node with children (the comparison is not vacuous)"
    # What DeviceScene asks before it collapses (does the tree fit the stack at this width?).
    assert bvh.wide_stack_needed(tree(case), width) == python[3].max()


def test_build_bvh_takes_the_compiled_build_from_compiled_from(monkeypatch):
    vertices, triangles = sphere_triangles(60, 30)
    monkeypatch.setattr(bvh, "COMPILED_FROM", len(triangles))
    calls = []
    for name in ("_build_numpy", "_build_compiled"):
        real = getattr(bvh, name)
        monkeypatch.setattr(bvh, name, lambda *a, real=real, name=name: calls.append(name) or real(*a))
    bvh.build_bvh(vertices, triangles)
    bvh.build_bvh(vertices, triangles[:-1])
    assert calls == ["_build_compiled", "_build_numpy"]


def test_a_build_in_its_own_process_gives_the_same_bvh_and_children(monkeypatch):
    """From SEPARATE_FROM triangles the build and the wide BVH's children come from a child process
    (build_process.py, which keeps numba out of the renderer): the same nodes, order, depth and
    children of each width as this process makes. The child's numba prints its cache's doings
    to stdout (NUMBA_DEBUG_CACHE): the arrays' pipe must not get them (it hung the build once)."""
    vertices, triangles = sphere_triangles(60, 30)
    here = bvh.build_bvh(vertices, triangles)
    monkeypatch.setattr(bvh, "SEPARATE_FROM", len(triangles))
    monkeypatch.setenv("NUMBA_DEBUG_CACHE", "1")
    there = bvh.build_bvh(vertices, triangles)
    assert sorted(there.children) == sorted(bvh.WIDE_NODES) and not here.children
    assert here.nodes.tobytes() == there.nodes.tobytes()
    assert np.array_equal(here.order, there.order) and here.max_depth == there.max_depth
    for width in bvh.WIDE_NODES:
        for what, x, y in zip(("kids", "index_of", "depth", "stack"),
                              bvh._wide_children(here.nodes, here.nodes["count"] > 0, width), there.children[width]):
            assert np.array_equal(x, y), (width, what)


def test_a_build_process_that_fails_is_an_error(monkeypatch):
    """A child that stops (here: numba cannot be imported) ends the build with an error, not a hang."""
    monkeypatch.setattr(bvh, "SEPARATE_FROM", 0)
    monkeypatch.setenv("PYTHONPATH", "")
    monkeypatch.setattr("sys.executable", "false")      # a program that exits 1 at once, reading nothing
    with pytest.raises(RuntimeError, match="BVH build process .* exit code 1"):
        bvh.build_bvh(*sphere_triangles(20, 10))


def test_million_scene_script_writes_the_box_and_sphere(tmp_path):
    """The benchmark scene at a small size: the box's 36 triangles and 2 x around x rings of the
    sphere, less the 2 x around at its poles that collapse to lines (the loader drops them)."""
    around, rings = 40, 20
    with pytest.warns(UserWarning, match=f"dropped {2 * around} degenerate"):
        scene = load_scene(make_million.write_million_scene(tmp_path, around, rings))
    assert len(scene.triangles) == 36 + 2 * around * rings - 2 * around
    sphere = scene.vertices[scene.triangles[36:]]
    radius = np.linalg.norm(sphere - make_million.CENTER, axis=2)
    assert np.allclose(radius, make_million.RADIUS)
    # Counter-clockwise seen from outside: face normals point away from the centre.
    normals = np.cross(sphere[:, 1] - sphere[:, 0], sphere[:, 2] - sphere[:, 0])
    assert (np.einsum("ij,ij->i", normals, sphere.mean(1) - make_million.CENTER) > 0).all()


def test_a_big_scene_s_load_starts_the_build_process_that_its_build_takes(tmp_path, monkeypatch):
    """A scene of big meshes starts the build's process before it reads them (its start runs on
    the other core meanwhile); the build takes that process and gets the same BVH from it."""
    from toolkit.core import build_process, scene as scene_module
    monkeypatch.setattr(scene_module, "BUILD_EARLY_FROM_BYTES", 1)
    monkeypatch.setattr(build_process, "_early", [])
    with pytest.warns(UserWarning, match="degenerate"):
        scene = load_scene(make_million.write_million_scene(tmp_path, 60, 30))
    assert len(build_process._early) == 1
    early = build_process._early[0]
    here = bvh.build_bvh(*rebased(scene))      # below SEPARATE_FROM: built here, the early child waits
    assert build_process._early == [early]
    monkeypatch.setattr(bvh, "SEPARATE_FROM", 1)
    there = bvh.build_bvh(*rebased(scene))
    assert build_process._early == [] and early.returncode == 0
    assert here.nodes.tobytes() == there.nodes.tobytes() and np.array_equal(here.order, there.order)


def test_an_early_build_process_that_no_build_takes_ends_quietly(monkeypatch, capfd):
    """Its parent ended (its stdin closed) before sending a scene: the child exits 0, saying nothing."""
    from toolkit.core import build_process
    monkeypatch.setattr(build_process, "_early", [])
    build_process.start_early()
    build_process.start_early()                 # one waits at a time
    assert len(build_process._early) == 1
    child = build_process._early.pop()
    child.stdin.close()
    assert child.wait(timeout=120) == 0 and child.stdout.read() == b""
    child.stdout.close()
    assert capfd.readouterr().err == ""


def test_a_big_scene_s_bvh_built_ahead_of_its_context_is_the_one_its_device_scene_takes(queue, cornell_box,
                                                                                         monkeypatch):
    """toolkit.render builds a big scene's BVH before it makes the OpenCL context (build_ahead:
    the build's process and the runtime are then never in memory together). The DeviceScene takes
    that BVH, the same as it would build; a scene already held by a context is not built again."""
    import weakref
    from toolkit.opencl import device_scene
    from toolkit.opencl.session import session
    kept = session()
    monkeypatch.setattr(device_scene, "SEPARATE_FROM", 1)
    monkeypatch.setattr(kept, "built_ahead", {})
    monkeypatch.setattr(kept, "held_bvhs", weakref.WeakValueDictionary())
    monkeypatch.setattr(queue.builds, "bvhs", {})
    scene = cornell_box
    device_scene.build_ahead(scene)
    ahead, = kept.built_ahead.values()
    taken = device_scene.DeviceScene(queue, scene)
    assert taken.bvh is ahead and kept.built_ahead == {}
    assert ahead.nodes.tobytes() == bvh.build_bvh(*device_scene._rebased(scene)[:1], scene.triangles).nodes.tobytes()
    device_scene.build_ahead(scene)             # held by the queue's context: nothing to build
    assert kept.built_ahead == {}
