"""The wide BVH (toolkit/core/bvh.py collapse_wide, cl/bvh.h under BVH_WIDE) against the binary one.

Both run the same float operations lane by lane (FP_CONTRACT off) and define the closest hit
the same way, ties included (smallest t, then lowest triangle index: cl/bvh.h `closer`), so
they must agree bit for bit: the same t, u, v and triangle for every ray, and the same image.
Only the order of visiting nodes differs, and the number of nodes visited.
"""
from dataclasses import replace

import numpy as np
import pytest

from toolkit import render
from toolkit.core.bvh import GROUP_WORDS
from toolkit.peers.embree import random_rays
from toolkit.opencl.device_scene import DeviceScene
from toolkit.peers.embree import camera_rays
from toolkit.core.layout import TRI_GROUP, WIDE_NODES, WideChild
from toolkit.opencl.raycast import DeviceRaycaster

SCENES = ["cornell_box", "cornell_spheres"]
# Both node widths on whatever device runs the tests: each has its own push (cl/bvh.h), and a
# device gets one of them (toolkit/opencl/device_scene.py node_width).
WIDTHS = [4, 8]


def _records(wide):
    words, node_words = wide.words, wide.node_words
    nodes = words[: wide.inner_nodes * node_words].reshape(-1).view(WIDE_NODES[wide.node_width].dtype)
    groups = words[wide.inner_nodes * node_words:].reshape(-1).view(TRI_GROUP.dtype)
    return nodes, groups


@pytest.mark.parametrize("width", WIDTHS)
@pytest.mark.parametrize("name", SCENES)
def test_collapse_keeps_every_triangle_once_and_the_root_box(queue, request, name, width):
    scene = request.getfixturevalue(name)
    wide = DeviceScene(queue, scene, bvh="wide", wide_width=width)
    assert wide.wide.node_width == width
    nodes, groups = _records(wide.wide)
    slots = groups["tri"][groups["tri"] >= 0]
    assert np.array_equal(np.sort(slots), np.arange(len(scene.triangles)))
    # Every leaf reference points at a group, every inner one at a node; each node is reached once.
    child = nodes["child"]
    inner, leaf = child[child >= 0], child[(child < 0) & (child != WideChild.EMPTY)]
    assert np.array_equal(np.sort(inner), np.arange(1, len(nodes)) * wide.wide.node_words)
    assert np.array_equal(np.sort(~leaf - len(nodes) * wide.wide.node_words), np.arange(len(groups)) * GROUP_WORDS)
    # Fewer than half as many nodes as the binary BVH's inner nodes: what cuts the traversal steps.
    assert len(nodes) <= 0.5 * max(wide.bvh.inner_nodes, 2)
    # The root's children together span the binary root's box.
    used = nodes["child"][0] != WideChild.EMPTY
    for k, axis in enumerate("xyz"):
        assert nodes[f"lo_{axis}"][0][used].min() == wide.bvh.nodes["lo"][0, k]
        assert nodes[f"hi_{axis}"][0][used].max() == wide.bvh.nodes["hi"][0, k]
    # Each group's vertices are the device triangles' float32 vertices, bit for bit.
    tris = wide.triangles
    lanes = groups["tri"] >= 0
    for v in range(3):
        for k, axis in enumerate("xyz"):
            assert np.array_equal(groups[f"v{v}{axis}"][lanes], tris[f"v{v}"][groups["tri"][lanes], k])


@pytest.mark.parametrize("width", WIDTHS)
@pytest.mark.parametrize("name", SCENES)
def test_wide_and_binary_find_bit_identical_hits(queue, request, name, width):
    scene = request.getfixturevalue(name)
    answers = {}
    for bvh in ("binary", "wide"):
        ds = DeviceScene(queue, scene, bvh=bvh, wide_width=width if bvh == "wide" else None)
        caster = DeviceRaycaster(queue, ds)
        o, d = random_rays(ds, 50_000, np.random.default_rng(1))
        co, cd = camera_rays(ds, 64, 64)
        o, d = np.concatenate([o, co]), np.concatenate([d, cd])
        tmax = np.random.default_rng(2).random(len(o)).astype(np.float32) * np.float32(ds.extent)
        answers[bvh] = (*caster.closest(o, d), caster.occluded(o, d, tmax))
    for what, a, b in zip(("t", "prim", "u", "v", "blocked"), answers["binary"], answers["wide"]):
        assert np.array_equal(a, b), what
    # The rays do hit things (the comparison is not vacuous).
    assert (answers["wide"][1] >= 0).mean() > 0.3


@pytest.mark.parametrize("name", SCENES)
def test_pt_naive_images_are_bit_identical(request, name):
    scene = request.getfixturevalue(name)
    images = {bvh: render(scene, "pt_naive", spp=4, resolution=(32, 32), bvh=bvh) for bvh in ("binary", "wide")}
    assert np.array_equal(images["binary"].image, images["wide"].image)
    steps = {bvh: r.stats["traversal_steps_per_sample"]["closest"] for bvh, r in images.items()}
    assert steps["wide"] < steps["binary"]


def test_a_scene_of_one_leaf(queue, cornell_box):
    """Four triangles or fewer: the binary root is a leaf, the wide root has one child."""
    keep = cornell_box.light_triangles[:2]      # a scene needs a light
    small = replace(cornell_box, triangles=cornell_box.triangles[keep], material_of=cornell_box.material_of[keep],
                    emission_of=cornell_box.emission_of[keep], name="two triangles")
    ds = DeviceScene(queue, small, bvh="wide")
    nodes, groups = _records(ds.wide)
    assert len(nodes) == 1 and len(groups) == 1
    o, d = camera_rays(ds, 16, 16)
    o = o - 0.5 * d       # from behind the light's plane too
    wide = DeviceRaycaster(queue, ds).closest(o, d)
    binary = DeviceRaycaster(queue, DeviceScene(queue, small, bvh="binary")).closest(o, d)
    for a, b in zip(binary, wide):
        assert np.array_equal(a, b)


def test_a_tree_too_deep_for_the_stack_at_eight_children_gets_four(queue, cornell_spheres, monkeypatch):
    """Eight children a level need more stack entries (cornell_spheres: 34 against 26 at four):
    where the stack holds too few for the 8-wide tree, the device gets the 4-wide one."""
    import toolkit.opencl.device_scene as device_scene
    needs = {w: DeviceScene(queue, cornell_spheres, bvh="wide", wide_width=w).wide.stack_needed for w in WIDTHS}
    assert needs[4] < needs[8]
    monkeypatch.setattr(device_scene, "node_width", lambda context: 8)
    monkeypatch.setattr(device_scene, "BVH_STACK_SIZE", needs[8] - 1)
    assert DeviceScene(queue, cornell_spheres, bvh="wide").wide.node_width == 4
