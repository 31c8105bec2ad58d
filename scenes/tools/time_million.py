"""Times the million-triangle scene's load and BVH build (issue 49): CPU seconds (this process and
and wall seconds of each step, and the process's peak memory. On a shared machine trust the
CPU seconds (the BVH build's own process included); the wall clock also counts other people's work.

    python scenes/tools/make_million.py out/million
    python scenes/tools/time_million.py out/million [--toolkit-load]

Steps: the meshes read by trimesh as arrays, or (--toolkit-load) the scene read as the renderer
reads it (the toolkit's load_scene, which also starts the BVH build's process early); the BVH
build on the rebased float64 triangles (toolkit/core/bvh.py, as DeviceScene calls it); the wide
BVH of 4 children (the one a million-triangle scene gets: its 8-wide tree needs more stack than
the kernels have). "load + BVH build" with --toolkit-load is the issue's target figure (check 1).
"""
import json
import resource
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent.parent
sys.path.insert(0, str(ROOT))


def cpu_seconds():
    """CPU seconds of this process and of the children it waited for (the BVH build's process)."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


class Clock:
    def __init__(self):
        self.rows = {}

    def __call__(self, name, step, *args):
        cpu, wall = cpu_seconds(), time.perf_counter()
        result = step(*args)
        self.rows[name] = (cpu_seconds() - cpu, time.perf_counter() - wall)
        print(f"{name:<34} {self.rows[name][0]:7.2f} s CPU {self.rows[name][1]:7.2f} s wall", flush=True)
        return result


def trimesh_arrays(scene_json):
    """Every mesh of the scene read by trimesh, as one (vertices, triangles) pair."""
    import trimesh
    vertices, triangles = [], []
    base = 0
    for shape in json.loads(scene_json.read_text(encoding="utf-8"))["shapes"]:
        mesh = trimesh.load(scene_json.parent / shape["mesh"], process=False)
        vertices.append(np.asarray(mesh.vertices, np.float64))
        triangles.append(np.asarray(mesh.faces, np.int64) + base)
        base += len(mesh.vertices)
    return np.concatenate(vertices), np.concatenate(triangles)


def toolkit_arrays(scene_json):
    """The scene as the renderer loads it (load_scene: the toolkit's OBJ reader, degenerate
    triangles dropped; a big scene's BVH process started as it reads), as (vertices, triangles)."""
    from toolkit.core.scene import load_scene
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")         # the sphere's 2,000 degenerate triangles, dropped
        scene = load_scene(scene_json)
    return scene.vertices, scene.triangles


def main(folder, toolkit_load=False):
    scene_json = Path(folder) / "scene.json"
    clock = Clock()
    from toolkit.core.bvh import SEPARATE_FROM, build_bvh, collapse_wide
    load = "load (toolkit's load_scene)" if toolkit_load else "load (trimesh)"
    vertices, triangles = clock(load, toolkit_arrays if toolkit_load else trimesh_arrays, scene_json)
    lo, hi = vertices.min(0), vertices.max(0)
    local = vertices - 0.5 * (lo + hi)
    if not toolkit_load:
        corners = local[triangles]
        edges = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        triangles = triangles[np.linalg.norm(edges, axis=1) > 0]     # the loader drops degenerate triangles too
        del corners, edges
    print(f"{len(triangles):,} triangles")
    bvh = clock("BVH build", build_bvh, local, triangles)
    leaf_vertices = local.astype(np.float32)[triangles[bvh.order]]
    wide = clock("wide BVH (4 children)", collapse_wide, bvh, leaf_vertices, 4)
    for steps in ((load, "BVH build"), (load, "BVH build", "wide BVH (4 children)")):
        cpu, wall = (sum(clock.rows[k][i] for k in steps) for i in (0, 1))
        print(f"{' + '.join(s.split(' (')[0] for s in steps):<34} {cpu:7.2f} s CPU {wall:7.2f} s wall")
    print(f"binary nodes {bvh.node_count:,}, depth {bvh.max_depth}; wide nodes {wide.inner_nodes:,}, "
          f"stack {wide.stack_needed}")
    print(f"peak memory (this process, all steps) {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB; "
          f"the BVH build's process (from {SEPARATE_FROM:,} triangles) "
          f"{resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024:.0f} MB")


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3) or sys.argv[2:] not in ([], ["--toolkit-load"]):
        print(f"usage: python {sys.argv[0]} SCENE_FOLDER [--toolkit-load] (the folder: scenes/tools/make_million.py's)",
              file=sys.stderr)
        raise SystemExit(2)
    main(sys.argv[1], toolkit_load=sys.argv[2:] == ["--toolkit-load"])
