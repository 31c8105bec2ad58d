"""Writes scenes/cornell_bunny: a real scan, the Stanford bunny, in the Cornell box. Run from the
checkout, with the source mesh unpacked from Debian's glmark2-data package (README.md says which
version, where the file is in it, and its licence):

    apt-get download glmark2-data && dpkg-deb -x glmark2-data_*.deb /tmp/glmark2
    pip install fast-simplification
    python scenes/cornell_bunny/make_scene.py /tmp/glmark2/usr/share/glmark2/models/bunny.obj

The scan is decimated from 69,666 to TRIANGLES triangles (quadric error metric, fast-simplification,
the library behind trimesh's simplify_quadric_decimation): the bunny covers 1,287 of the
reference's 128 x 128 pixels, so 16,000 triangles are still ~12 per pixel (the silhouette and the
shading are the scan's, and a warp's rays still reach different leaves: the traversal divergence
this scene is for), the BVH is 2 levels shallower than the full scan's, and the mesh is 304 KB
in the repository instead of 1.3 MB. The box is cornell_box's without its two blocks.

The mesh keeps the source's coordinates (y up, scaled to [-1, 1] in x); scene.json places it with
a transform (scenes/FORMAT.md: Transforms): half size, turned to face the camera, on the floor.
"""
import json
import shutil
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
BOX = HERE.parent / "cornell_box"
TRIANGLES = 16000
BOX_PARTS = ["floor", "ceiling", "back", "green_wall", "red_wall", "light"]
SCALE = 0.5
TURN_DEG = 30.0               # about the vertical: the bunny's face towards the camera


def decimated(source):
    """The scan's vertices and triangles, decimated to TRIANGLES with the quadric error metric."""
    import fast_simplification
    import trimesh
    mesh = trimesh.load(source, process=False, force="mesh")
    points, faces = fast_simplification.simplify(mesh.vertices.astype(np.float64), mesh.faces,
                                                 target_count=TRIANGLES)
    return trimesh.Trimesh(points, faces, process=False), mesh


def scene(floor_y):
    box = json.loads((BOX / "scene.json").read_text())
    shapes = [s for s in box["shapes"] if Path(s["mesh"]).stem in BOX_PARTS]
    box["camera"].update(width=128, height=128)
    shapes.append({"mesh": "meshes/bunny.ply", "material": "white",
                   "transform": [{"scale": SCALE},
                                 {"rotate": {"axis": [0, 1, 0], "angle_deg": TURN_DEG}},
                                 {"translate": [0, floor_y, 0]}]})
    box["shapes"] = shapes
    box["notes"] = ("The Stanford bunny (a range scan; Debian glmark2-data's bunny.obj, decimated to "
                    f"{TRIANGLES} triangles by make_scene.py) in cornell_box without its blocks; "
                    "README.md gives its source and licence")
    return box


def main(argv):
    if len(argv) != 1:
        print(__doc__)
        return 2
    bunny, source = decimated(argv[0])
    print(f"{len(source.faces)} -> {len(bunny.faces)} triangles; watertight {bunny.is_watertight}")
    (HERE / "meshes").mkdir(exist_ok=True)
    (HERE / "meshes" / "bunny.ply").write_bytes(bunny.export(file_type="ply", encoding="binary"))
    for part in BOX_PARTS:
        shutil.copyfile(BOX / "meshes" / f"{part}.obj", HERE / "meshes" / f"{part}.obj")
    floor_y = -1.0 - SCALE * float(bunny.vertices[:, 1].min())     # its lowest point on the floor
    (HERE / "scene.json").write_text(json.dumps(scene(round(floor_y, 6)), indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
