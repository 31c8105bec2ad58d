"""Writes the million-triangle benchmark scene (issue 49): the Cornell box with a UV sphere of
1,000 x 500 segments resting on its small box. The sphere's 1,000,000 triangles include the
2,000 at its poles that collapse to a line (a quad's two corners meet there); the loader drops
those, which leaves 998,000 of the sphere and the box's 36: 998,036.

Made on demand, not committed (a 70 MB OBJ): `python scenes/tools/make_million.py OUT_FOLDER`
writes OUT_FOLDER/scene.json and its meshes, and `python -m toolkit render OUT_FOLDER` renders it.
`--segments 100x50` writes a smaller sphere of the same kind (the tests use one).
"""
import argparse
import json
import shutil
import sys
from pathlib import Path

import numpy as np

BOX = Path(__file__).resolve().parent.parent / "cornell_box"
CENTER, RADIUS = (0.335, -0.1, 0.38), 0.3      # on the small box's top (y = -0.4)


def uv_sphere(around, rings, center=CENTER, radius=RADIUS):
    """(vertices (n, 3), triangles (m, 3) 0-based): `around` segments of longitude by `rings` of
    latitude, two triangles per quad, counter-clockwise seen from outside. Each ring is its own
    row of vertices, the poles included (so a pole's quads have two coincident corners)."""
    theta = np.linspace(0.0, np.pi, rings + 1)[:, None]           # from the north pole down
    phi = np.linspace(0.0, 2.0 * np.pi, around, endpoint=False)[None, :]
    xyz = np.stack(np.broadcast_arrays(np.sin(theta) * np.cos(phi), np.cos(theta),
                                       -np.sin(theta) * np.sin(phi)), axis=-1)
    vertices = np.asarray(center) + radius * xyz.reshape(-1, 3)
    row, col = np.meshgrid(np.arange(rings), np.arange(around), indexing="ij")
    a = row * around + col                      # this ring
    b = row * around + (col + 1) % around       # next around
    c, d = a + around, b + around               # the ring below
    triangles = np.concatenate([np.stack([a, c, d], -1).reshape(-1, 3), np.stack([a, d, b], -1).reshape(-1, 3)])
    return vertices, triangles


def write_obj(path, vertices, triangles):
    """An OBJ of `v` and `f` lines (1-based), written with numpy's formatter in one pass."""
    with open(path, "w", encoding="ascii") as f:
        f.write(f"# toolkit-scene/1 mesh: {len(vertices)} vertices, {len(triangles)} triangles\n")
        np.savetxt(f, vertices, fmt="v %.9g %.9g %.9g")
        np.savetxt(f, triangles + 1, fmt="f %d %d %d")


def write_million_scene(folder, around=1000, rings=500):
    """The Cornell box (scenes/cornell_box, its references left out) plus a sphere of
    around x rings segments, in `folder`; returns the scene.json path."""
    folder = Path(folder)
    (folder / "meshes").mkdir(parents=True, exist_ok=True)
    scene = json.loads((BOX / "scene.json").read_text(encoding="utf-8"))
    for shape in scene["shapes"]:
        shutil.copyfile(BOX / shape["mesh"], folder / shape["mesh"])
    write_obj(folder / "meshes" / "sphere.obj", *uv_sphere(around, rings))
    scene["shapes"].append({"mesh": "meshes/sphere.obj", "material": "white"})
    scene["notes"] = f"The Cornell box with a UV sphere of {around} x {rings} segments (scenes/tools/make_million.py)."
    (folder / "scene.json").write_text(json.dumps(scene, indent=2), encoding="utf-8")
    return folder / "scene.json"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", type=Path, help="where to write scene.json and meshes/ (made if missing)")
    parser.add_argument("--segments", default="1000x500", help="AROUNDxRINGS of the sphere (default 1000x500)")
    args = parser.parse_args(argv)
    try:
        around, rings = (int(n) for n in args.segments.lower().split("x"))
        if not (3 <= around <= 4000 and 2 <= rings <= 2000):
            raise ValueError
    except ValueError:
        parser.error(f"--segments must be AROUNDxRINGS with 3..4000 around and 2..2000 rings, got {args.segments!r}")
    print(write_million_scene(args.folder, around, rings))
    return 0


if __name__ == "__main__":
    sys.exit(main())
