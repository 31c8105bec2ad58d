"""Every hostile scene file of issue 49 item 5 through the command line, as a learner meets it:
`python -m toolkit render <file>` in its own process, under an address-space cap and a timeout.

    python tests/hostile_files_cli.py [--root CHECKOUT] [--only NAME,NAME] [--keep FOLDER]

For each case it prints the exit code, the wall time, the peak memory, whether a traceback was
printed and the error line, and checks what the team asks of bad input: exit 2, no traceback, one
`error:` line naming the file and the problem. Exit code 1 if any case does not. `--root` runs
another checkout's toolkit (an older commit, or one with a guard taken out), to see what a case
gave there. The suite's tests of each case are tests/test_mitsuba_xml.py and
tests/test_mesh_files.py; this script is the end-to-end look, run by hand (results/issue49_
hostile_seen_failing.md), not in the suite: ~1 s a case.
"""
import argparse
import json
import resource
import shutil
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent
ADDRESS_SPACE = 4 << 30     # bytes: a blow-up fails here, not on the shared machine
TIMEOUT = 120               # seconds


def binary_ply(vertices, faces, body):
    return (f"ply\nformat binary_little_endian 1.0\nelement vertex {vertices}\nproperty float x\nproperty float y\n"
            f"property float z\nelement face {faces}\nproperty list uchar int vertex_indices\nend_header\n"
            ).encode() + body


TRIANGLE = struct.pack("<9f", -1, -1, 1, 1, -1, 1, 1, -1, -1)


def face(*ids):
    return struct.pack(f"<B{len(ids)}i", len(ids), *ids)


def many_placements_glb(copies=1000, n=100):
    """0.4 MB: one mesh of 2 n^2 triangles placed by `copies` nodes (20 million triangles joined)."""
    import numpy as np
    u = np.linspace(-1, 1, n + 1, dtype=np.float32)
    x, z = np.meshgrid(u, u)
    positions = np.stack([x.ravel(), np.full(x.size, -1, np.float32), z.ravel()], 1).astype(np.float32)
    i = np.arange(n * n) + np.arange(n * n) // n
    indices = np.stack([i, i + n + 1, i + n + 2, i, i + n + 2, i + 1], 1).astype(np.uint32).ravel()
    blob = positions.tobytes() + indices.tobytes()
    document = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
                "nodes": [{"children": list(range(1, copies + 1))}] + [{"mesh": 0}] * copies,
                "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
                "buffers": [{"byteLength": len(blob)}],
                "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": positions.nbytes},
                                {"buffer": 0, "byteOffset": positions.nbytes, "byteLength": indices.nbytes}],
                "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(positions), "type": "VEC3",
                               "min": positions.min(0).tolist(), "max": positions.max(0).tolist()},
                              {"bufferView": 1, "componentType": 5125, "count": len(indices), "type": "SCALAR"}]}
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    return (struct.pack("<4sII", b"glTF", 2, 28 + len(text) + len(blob)) + struct.pack("<I4s", len(text), b"JSON")
            + text + struct.pack("<I4s", len(blob), b"BIN\0") + blob)


def xml_cases(folder):
    """{name: (file to render, [fragments its error line must hold])}: Mitsuba XML scenes."""
    cases = {}

    def case(name, text, *fragments, extra=()):
        sub = folder / name
        sub.mkdir()
        for file, content in extra:
            (sub / file).write_text(content)
        (sub / "scene.xml").write_text(text)
        cases[name] = (sub / "scene.xml", [*fragments])

    case("xml-malformed", '<scene version="3.0.0">\n<shape type="cube">\n</scene>', "scene.xml:3", "malformed XML")
    case("xml-self-include", '<scene><include filename="scene.xml"/></scene>', "scene.xml:1",
         "include cycle: scene.xml includes scene.xml")
    case("xml-include-cycle", '<scene><include filename="b.xml"/></scene>', "b.xml:2", "include cycle",
         extra=[("b.xml", '<scene>\n<include filename="scene.xml"/></scene>')])
    entities = '<!ENTITY l0 "lol">' + "".join(f'<!ENTITY l{k} "{("&l%d;" % (k - 1)) * 10}">' for k in range(1, 10))
    case("xml-billion-laughs", f'<?xml version="1.0"?>\n<!DOCTYPE scene [{entities}]>\n<scene><string name="x" '
         'value="&l9;"/></scene>', "scene.xml", "refused XML")
    case("xml-quadratic-blowup", f'<?xml version="1.0"?>\n<!DOCTYPE scene [<!ENTITY a "{"x" * 100000}">]>\n'
         f'<scene><string name="x" value="{"&a;" * 100000}"/></scene>', "scene.xml", "refused XML")
    case("xml-external-entity", '<?xml version="1.0"?>\n<!DOCTYPE scene [<!ENTITY e SYSTEM "file:///etc/passwd">]>'
         '\n<scene>&e;</scene>', "scene.xml", "refused XML")
    case("xml-deep-nesting", "<scene>" + "<shape>" * 100000 + "</shape>" * 100000 + "</scene>", "scene.xml:1",
         "element nesting depth")
    twice = '<include filename="f{0}.xml"/>' * 2
    fan = [(f"f{k}.xml", f'<scene><!--{"x" * 400}-->{twice.format(k + 1)}</scene>') for k in range(1, 16)]
    fan.append(("f16.xml", "<scene/>"))
    case("xml-include-fan-out", '<scene><include filename="f1.xml"/><include filename="f1.xml"/></scene>',
         "XML files parsed for this scene", extra=fan)
    case("xml-include-bytes", '<scene><include filename="big.xml"/><include filename="big.xml"/></scene>',
         "big.xml", "XML read for this scene", extra=[("big.xml", "<scene><!--" + "x" * (9 << 20) + "--></scene>")])
    case("xml-include-outside", '<scene><include filename="../outside.xml"/></scene>', "scene.xml:1",
         "must be inside the scene folder")
    case("xml-nan", '<scene version="3.0.0">\n<shape type="cube"><transform name="to_world"><translate '
         'value="nan 0 0"/></transform></shape></scene>', "scene.xml:2", "NaN or infinite value in <translate>")
    case("xml-is-json", (HERE / "scenes" / "cornell_box" / "scene.json").read_text(), "scene.xml:1",
         "malformed XML")
    case("xml-names-hostile-ply", '<scene version="3.0.0">\n<shape type="ply"><string name="filename" '
         'value="huge.ply"/></shape></scene>', "huge.ply", "claims 3000000000 vertices")
    (folder / "xml-names-hostile-ply" / "huge.ply").write_bytes(binary_ply(3_000_000_000, 1, TRIANGLE + face(0, 1, 2)))
    return cases


def mesh_cases(folder):
    """{name: (scene folder to render, [fragments])}: the Cornell box with its floor a hostile mesh."""
    off = b"OFF\n3 1 0\n-1 -1 1\n1 -1 1\n1 -1 -1\n"
    floor = (HERE / "scenes" / "cornell_box" / "meshes" / "floor.obj").read_bytes()
    nan_stl = (b"\0" * 80 + struct.pack("<I", 1) + struct.pack("<12f", 0, 0, 1, 0, 0, 0, 1, float("nan"), 0, 0, 1, 0)
               + b"\0\0")
    meshes = {
        "ply-billions-of-vertices": ("huge.ply", binary_ply(3_000_000_000, 1, TRIANGLE + face(0, 1, 2)),
                                     "claims 3000000000 vertices"),
        "ply-billions-of-faces": ("huge.ply", binary_ply(3, 4_000_000_000, TRIANGLE + face(0, 1, 2)),
                                  "claims 4000000000 faces"),
        "ply-ascii-claims-more-lines": ("short.ply", b"ply\nformat ascii 1.0\nelement vertex 2000000\nproperty float x"
                                        b"\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar "
                                        b"int vertex_indices\nend_header\n-1 -1 1\n1 -1 1\n1 -1 -1\n3 0 1 2\n",
                                        "claims 2000000 vertex"),
        "ply-face-past-the-vertices": ("past.ply", binary_ply(3, 1, TRIANGLE + face(0, 1, 7)),
                                       "face 0 indexes vertex 7"),
        "ply-negative-index": ("negative.ply", binary_ply(3, 1, TRIANGLE + face(0, -1, 2)), "face 0 indexes vertex -1"),
        "off-face-past-the-vertices": ("past.off", off + b"3 0 1 5\n", "face index outside the range"),
        "ply-nan": ("nan.ply", binary_ply(3, 1, struct.pack("<9f", -1, -1, 1, float("nan"), -1, 1, 1, -1, -1)
                                          + face(0, 1, 2)), "NaN or infinite coordinate"),
        "off-inf": ("inf.off", b"OFF\n3 1 0\n-1 -1 1\n1 -1 inf\n1 -1 -1\n3 0 1 2\n", "NaN or infinite coordinate"),
        "stl-nan": ("nan.stl", nan_stl, "NaN or infinite coordinate"),
        "obj-text-named-ply": ("obj_text.ply", floor, "not a PLY file"),
        "text-named-glb": ("text.glb", b'{"asset": {"version": "2.0"}}', "not a GLB file"),
        "noise-named-stl": ("noise.stl", bytes(range(256)) * 3, "not an STL file"),
        "ply-named-obj": ("ply_bytes.obj", binary_ply(3, 1, TRIANGLE + face(0, 1, 2)), "cannot read mesh"),
        "glb-places-a-mesh-1000-times": ("many.glb", many_placements_glb(), "more than the scene has room for"),
        "gltf-names-another-file": ("outside.gltf", json.dumps({"asset": {"version": "2.0"}, "buffers": [
            {"uri": "../../secret.bin", "byteLength": 36}]}).encode(), "refers to another file"),
    }
    cases = {}
    for name, (file, data, problem) in meshes.items():
        box = folder / name
        shutil.copytree(HERE / "scenes" / "cornell_box", box, ignore=shutil.ignore_patterns("*.exr"))
        (box / "meshes" / file).write_bytes(data)
        scene = json.loads((box / "scene.json").read_text())
        scene["shapes"][0]["mesh"] = f"meshes/{file}"
        (box / "scene.json").write_text(json.dumps(scene))
        cases[name] = (box, [f"meshes/{file}", problem])
    return cases


def cap_memory():
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))


def run(root, path, out):
    """(exit code, wall seconds, peak MB of the child, stderr) of one render."""
    start = time.perf_counter()
    try:
        child = subprocess.run([sys.executable, "-m", "toolkit", "render", str(path), "--spp", "1", "--resolution",
                                "8x8", "--no-progress", "--out", str(out)], cwd=root, capture_output=True, text=True,
                               timeout=TIMEOUT, preexec_fn=cap_memory)
        code, stderr = child.returncode, child.stderr
    except subprocess.TimeoutExpired as error:
        code, stderr = "timeout", (error.stderr or b"").decode(errors="replace")
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss // 1024
    return code, time.perf_counter() - start, peak, stderr


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--root", type=Path, default=HERE, help="the checkout whose toolkit runs (default: this one)")
    parser.add_argument("--only", help="comma-separated case names")
    parser.add_argument("--keep", type=Path, help="make the cases in this folder and keep them")
    args = parser.parse_args()
    folder = args.keep or Path(tempfile.mkdtemp(prefix="hostile-cli-"))
    folder.mkdir(parents=True, exist_ok=True)
    cases = {**xml_cases(folder), **mesh_cases(folder)}
    names = args.only.split(",") if args.only else list(cases)
    print("| case | exit | wall s | peak MB | traceback | error line |\n|---|---|---|---|---|---|")
    bad = 0
    for name in names:
        path, fragments = cases[name]
        # Each child's peak is its own: RUSAGE_CHILDREN is the largest child so far, so run each
        # case in a fresh grandparent to read it alone.
        probe = subprocess.run([sys.executable, "-c", f"import sys; sys.path.insert(0, {str(HERE / 'tests')!r}); "
                                f"import hostile_files_cli as h, json; print(json.dumps(h.run({str(args.root)!r}, "
                                f"{str(path)!r}, {str(folder / 'out.exr')!r})))"], capture_output=True, text=True)
        code, wall, peak, stderr = json.loads(probe.stdout)
        errors = [line for line in stderr.splitlines() if line.startswith("error: ")]
        traceback = "Traceback" in stderr
        shown = errors[0] if errors else (stderr.strip().splitlines() or ["(nothing)"])[-1]
        # Exit 2, no traceback, one error line naming a file of the case (by its path) and the problem.
        ok = (code == 2 and not traceback and len(errors) == 1 and f"{name}/" in errors[0]
              and all(f in errors[0] for f in fragments))
        bad += not ok
        shown = shown.replace(str(folder) + "/", "").replace("|", "/")
        print(f"| {name}{'' if ok else ' **(not as asked)**'} | {code} | {wall:.1f} | {peak} | "
              f"{'yes' if traceback else 'no'} | `{shown[:160]}` |")
    if not args.keep:
        shutil.rmtree(folder)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
