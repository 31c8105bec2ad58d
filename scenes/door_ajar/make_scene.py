"""Writes scenes/door_ajar: Veach's door ajar (Veach 1997, fig. 11.3), the scene Metropolis
light transport was made for. Run from the checkout: `python scenes/door_ajar/make_scene.py`.

Two rooms share a wall at z = 0: room A (z < 0) holds the lamp, room B (z > 0) the camera.
The only opening is a doorway whose door is ajar by DOOR_DEGREES into room A, so room B is lit
only through the crack between the door's free edge and the frame. The lamp is a wall washer:
it faces the back wall of room A from LAMP_GAP away, so no point of the rooms but that wall sees
its emitting side, and all light leaves it by that wall. Every path that carries light to the
camera crosses the crack, and a path tracer must also find the washed wall by chance (its
shadow rays to the lamp are blocked everywhere else): BDPT's light subpaths start there, so it
beats the path tracer, but they pass the crack rarely. Once a path through the crack is found,
its neighbours carry light too, and a Metropolis chain explores them.

The camera stands on the crack's closed side (x > the doorway), so no pixel looks through the
crack into the bright room: the chains' bright, hard-to-leave pixels (results/issue10_mlt.md,
covered_lamp's slit) are left out on purpose. Diffuse materials only: a scene with the same
features as covered_lamp reuses its compiled kernels.
"""
import json
import math
from pathlib import Path

HERE = Path(__file__).resolve().parent
DOOR_DEGREES = 5.0           # how far the door is ajar
ROOM_X, ROOM_Y, ROOM_Z = 1.5, 2.4, 3.0   # half-width, height, depth of each room
DOOR_X, DOOR_TOP = 0.45, 2.0  # the doorway's half-width and height
DOOR_HEIGHT = 2.1            # the door overlaps the lintel behind it: no crack along its top
LAMP_GAP = 0.15              # from the lamp to the wall it faces


def quad(a, b, c, d):
    """Two triangles, counter-clockwise a b c d (the face normal by the right-hand rule)."""
    return [a, b, c, d], [(1, 2, 3), (1, 3, 4)]


def box(x0, x1, y0, y1, z0, z1):
    """An axis-aligned box, faces outwards."""
    v = [(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)]
    faces = [(1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)]
    tris = [t for a, b, c, d in faces for t in ((a, b, c), (a, c, d))]
    return v, tris


def door():
    """The door: hinged at the doorway's left edge (x = -DOOR_X, z = 0), turned into room A."""
    t = math.radians(DOOR_DEGREES)
    hinge_x, free = -DOOR_X, (-DOOR_X + 2 * DOOR_X * math.cos(t), -2 * DOOR_X * math.sin(t))
    return quad((hinge_x, 0, 0), (free[0], 0, free[1]), (free[0], DOOR_HEIGHT, free[1]), (hinge_x, DOOR_HEIGHT, 0))


def meshes():
    X, Y, Z = ROOM_X, ROOM_Y, ROOM_Z
    return {
        "floor": quad((-X, 0, Z), (X, 0, Z), (X, 0, -Z), (-X, 0, -Z)),
        "ceiling": quad((-X, Y, -Z), (X, Y, -Z), (X, Y, Z), (-X, Y, Z)),
        "wall_left": quad((-X, 0, -Z), (-X, 0, Z), (-X, Y, Z), (-X, Y, -Z)),
        "wall_right": quad((X, 0, Z), (X, 0, -Z), (X, Y, -Z), (X, Y, Z)),
        "wall_back_b": quad((X, 0, Z), (-X, 0, Z), (-X, Y, Z), (X, Y, Z)),
        "wall_back_a": quad((-X, 0, -Z), (X, 0, -Z), (X, Y, -Z), (-X, Y, -Z)),
        # the shared wall at z = 0, around the doorway
        "wall_door_left": quad((-X, 0, 0), (-DOOR_X, 0, 0), (-DOOR_X, Y, 0), (-X, Y, 0)),
        "wall_door_right": quad((DOOR_X, 0, 0), (X, 0, 0), (X, Y, 0), (DOOR_X, Y, 0)),
        "lintel": quad((-DOOR_X, DOOR_TOP, 0), (DOOR_X, DOOR_TOP, 0), (DOOR_X, Y, 0), (-DOOR_X, Y, 0)),
        "door": door(),
        "table": box(-1.1, -0.5, 0.0, 0.55, 1.0, 1.7),    # something in room B to catch the light
        # the lamp: a wall washer at the back of room A, facing the back wall (-z) from LAMP_GAP
        "lamp": quad((-0.4, 1.2, -Z + LAMP_GAP), (-0.4, 1.7, -Z + LAMP_GAP), (0.4, 1.7, -Z + LAMP_GAP),
                     (0.4, 1.2, -Z + LAMP_GAP)),
    }


MATERIALS = {
    "wall": {"type": "diffuse", "reflectance": [0.8, 0.8, 0.8]},
    "floor": {"type": "diffuse", "reflectance": [0.6, 0.5, 0.4]},
    "door": {"type": "diffuse", "reflectance": [0.55, 0.35, 0.2]},
    "table": {"type": "diffuse", "reflectance": [0.25, 0.4, 0.7]},
    "lamp": {"type": "diffuse", "reflectance": [0.0, 0.0, 0.0]},
}
MATERIAL_OF = {"floor": "floor", "door": "door", "table": "table", "lamp": "lamp"}
EMISSION = [400.0, 360.0, 290.0]


def write_obj(path, vertices, triangles):
    lines = [f"# toolkit-scene/1 mesh: {len(vertices)} vertices, {len(triangles)} triangles"]
    lines += [f"v {x:.6g} {y:.6g} {z:.6g}" for x, y, z in vertices]
    lines += [f"f {a} {b} {c}" for a, b, c in triangles]
    path.write_text("\n".join(lines) + "\n")


def main():
    (HERE / "meshes").mkdir(exist_ok=True)
    shapes = []
    for name, (v, t) in meshes().items():
        write_obj(HERE / "meshes" / f"{name}.obj", v, t)
        shape = {"mesh": f"meshes/{name}.obj", "material": MATERIAL_OF.get(name, "wall")}
        if name == "lamp":
            shape["emission"] = EMISSION
        shapes.append(shape)
    scene = {
        "format": "toolkit-scene/1",
        "camera": {"origin": [1.25, 1.3, 2.85], "target": [-0.45, 0.55, 0.0], "up": [0.0, 1.0, 0.0],
                   "fov_deg": 70.0, "fov_axis": "x", "width": 64, "height": 64},
        "materials": MATERIALS,
        "shapes": shapes,
        "integrator": {"max_depth": -1, "rr_depth": 5},
        "notes": (f"Veach's door ajar: the lamp in room A, the camera in room B, the door ajar by {DOOR_DEGREES:g} "
                  "degrees; room B is lit only through the crack, and the lamp only by the wall it washes (Metropolis test scene; "
                  "made by make_scene.py)"),
    }
    (HERE / "scene.json").write_text(json.dumps(scene, indent=2) + "\n")


if __name__ == "__main__":
    main()
