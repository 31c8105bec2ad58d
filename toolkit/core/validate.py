"""Every limit on what the toolkit accepts, in one table, and the checks shared by the scene
loader (scene.py), the command line (toolkit/cli/) and `toolkit.render` (api.py).

scenes/FORMAT.md states each limit of LIMITS in its "Limits" table; a test
(tests/test_bad_input.py) checks the document against this table, so they cannot drift apart.
"""
import difflib
import math
import numbers
import os
import stat
import tempfile
from pathlib import Path

from toolkit.core.layout import LONGEST_SUBPATH
from toolkit.core.sample_dims import used_dims
from toolkit.core.errors import InputError  # noqa: F401  (defined there; every caller imports it from here too)


# name: (lowest, highest, why). Names are how FORMAT.md and the error messages call them.
LIMITS = {
    "camera.width": (1, 1 << 15, "pixels"),
    "camera.height": (1, 1 << 15, "pixels"),
    "camera.fov_deg": (1e-3, 179.0, "a pinhole cannot see 180 degrees"),
    "material.reflectance": (0.0, 1.0, "above 1 creates energy"),
    "material.ior": (1.000001, 10.0, "relative to the exterior (index 1)"),
    "material.alpha": (1e-4, 1.0, "GGX roughness; smoother: use a mirror"),
    "shape.emission": (1e-10, 1e10, "each non-zero component; 0 means no light. Products with "
                                    "areas and densities must stay inside float32"),
    "integrator.max_depth": (-1, LONGEST_SUBPATH - 1,
                             f"-1: unbounded. BDPT stores at most {LONGEST_SUBPATH} vertices per subpath"),
    "integrator.rr_depth": (-1, 63, "-1: no Russian roulette (then max_depth must be set)"),
    "integrator.clamp": (1e-6, 1e10, "largest RGB component of one sample's contribution; absent or null: no "
                                     "clamping (unbiased)"),
    # Measured: the Cornell box renders the same at scales 1e-12 .. 1e12; the margin leaves room
    # for extreme emission, whose products with areas and densities also live in float32.
    "scene.extent": (1e-6, 1e6, "bounding-box diagonal"),
    "scene.offset": (0.0, 1e6, "distance of the scene's centre from the origin, in extents "
                               "(float64 rebasing keeps 1e-10 of the extent)"),
    "camera.distance": (0.0, 100.0, "camera origin from the scene's centre, in extents: float32 hit "
                                    "points stay within the ray offset (1e-5 extents)"),
    "scene.triangles": (1, 1 << 24, "as read (the reader stops there), and after dropping degenerate ones"),
    "scene.vertices": (1, 1 << 26, "`v` lines of all meshes (the reader stops there): 3 per triangle leaves room "
                                   "for meshes that share no vertex"),
    "mesh.bytes": (1, 1 << 31, "size of one mesh file"),
    # trimesh's text parsers hold every line as Python strings: measured 18 to 19 times the file in
    # memory (an 80 MB ASCII PLY or OFF of 2 million triangles: 1.4 to 1.5 GB), so at most ~1.3 GB here.
    "mesh.text_bytes": (1, 1 << 26, "size of one ASCII PLY, ASCII STL, OFF or glTF file (trimesh parses them in "
                                    "memory); larger meshes: binary PLY, binary STL, GLB or OBJ"),
    "mesh.line_length": (0, 1 << 16, "characters of one line of an OBJ file"),
    "scene.json.bytes": (1, 1 << 24, "size of scene.json"),
    "scene.json.depth": (0, 16, "nesting of JSON objects and lists"),
    "scene.xml.bytes": (1, 1 << 24, "Mitsuba XML read for one scene: the main file and every include, counted each "
                                    "time it is included"),
    "scene.xml.files": (1, 4096, "Mitsuba XML files parsed for one scene: the main file and every include, counted "
                                 "each time it is included (a fan-out of small files costs parses, not bytes)"),
    "scene.xml.depth": (1, 64, "nesting of XML elements in one Mitsuba XML file"),
    "scene.xml.includes": (1, 16, "nesting of Mitsuba XML includes (a cycle is refused at once)"),
    "spp": (1, 1 << 24, "samples per pixel of one render"),
    "seed": (0, (1 << 32) - 1, "the device hashes it as a 32-bit unsigned integer"),
    "memory.fraction": (0.0, 0.5, "film and device buffers, as a share of this machine's memory"),
    "bench.equal_time": (0.01, 86400.0, "seconds per technique"),
    "bench.repeats": (1, 1000, "interleaved repetitions"),
    "render.strategy_images": (1, 10, "edges of the longest paths with per-strategy images of their own "
                                      "((K + 1)(K + 2) / 2 images at most)"),
    "study.repeats": (1, 1000, "independent repetitions per budget"),
    "study.budget": (1e-3, 86400.0, "seconds of rendering per repetition"),
    "study.target": (1e-6, 10.0, "relative RMSE target (a fraction of the reference image's mean)"),
    "crosscheck.rays": (1, 1 << 26, "random rays"),
    # Technique options, stated in FORMAT.md's second table.
    "technique.local_size": (32, 256, "work-items per work-group, a power of two (toolkit.render's local_size); "
                                      "the image does not depend on it"),
    "technique.stream_size": (1, 1 << 24, "paths in flight in pt_inplace_regen and pt_compact_regen; "
                                          "default from the device (`python -m toolkit devices`)"),
    "technique.pool_size": (1, 1 << 22, "samples in flight in the BDPT techniques and mlt; "
                                        "default from the device"),
    "technique.pass_spp": (1, 1 << 24, "samples per pixel in one pass (default: the technique's batch size); "
                                       "cost only, the image does not depend on it"),
    "mlt.chains": (1, 1 << 18, "independent Metropolis chains; each stores two vectors of max_dims floats"),
    "mlt.large_step": (1e-3, 1.0, "probability of a large step; b comes from the large steps"),
    "mlt.candidates": (1, 1024, "large steps per chain for start = pool or resample"),
    "mlt.time_limit": (1e-3, 1e6, "seconds after which an mlt render stops (it keeps the mutations made so far)"),
    "mlt.max_dims": (8, int(used_dims(LONGEST_SUBPATH, LONGEST_SUBPATH)),
                     f"stored primary-sample dimensions per chain (8 + 8 per vertex after the first: the most holds "
                     f"{LONGEST_SUBPATH} vertices)"),
    "mlt.small_step": (1e-3, 0.5, "largest size of a small step (Kelemen's s2; the smallest, s1, is a sixteenth of it)"),
}


def limit_text(name):
    """`low .. high` as FORMAT.md writes it."""
    low, high, _ = LIMITS[name]
    return f"{_num(low)} .. {_num(high)}"


def _num(x):
    if isinstance(x, int) and x >= 1024 and (x & (x - 1)) == 0:
        return f"2^{x.bit_length() - 1}"
    if isinstance(x, int) and x + 1 >= 1024 and ((x + 1) & x) == 0:
        return f"2^{x.bit_length()} - 1"
    text, short = f"{x:.7g}", f"{x:.0e}"
    return short if float(short) == x and len(short) < len(text) else text


def in_range(name, value, where=None):
    """`value` if it lies within LIMITS[name], else an InputError naming `where` (default the name)."""
    low, high, _ = LIMITS[name]
    if not low <= value <= high:
        raise InputError(f"{where or name} {_show(value)} is outside {limit_text(name)}")
    return value


def _show(value):
    return repr(value)


def whole_number(name, value, where=None):
    """An int (not a bool, not 2.0) within LIMITS[name]."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise InputError(f"{where or name} must be a whole number, got {value!r}")
    return in_range(name, int(value), where)


def finite_number(name, value, where=None):
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(f"{where or name} must be a number, got {value!r}")
    try:
        value = float(value)
    except OverflowError:
        raise InputError(f"{where or name} {value!r} is outside {limit_text(name)}") from None
    if not math.isfinite(value):
        raise InputError(f"{where or name} must be finite, got {value!r}")
    return in_range(name, value, where)


# -- unknown keys ------------------------------------------------------------------------------

# Names other renderers use for our keys: a misspelt "roughnes" should still lead to "alpha".
SYNONYMS = {"roughness": "alpha", "albedo": "reflectance", "color": "reflectance", "eta": "ior",
            "radiance": "emission", "fov": "fov_deg", "maxdepth": "max_depth", "rrdepth": "rr_depth"}


def check_keys(where, obj, known, what):
    """Refuse keys of `obj` outside `known` (plus a free-form "notes"), suggesting the closest."""
    for key in obj:
        if key in known or key == "notes":
            continue
        candidates = sorted(known | {s for s, k in SYNONYMS.items() if k in known})
        close = [SYNONYMS.get(c, c) for c in difflib.get_close_matches(key, candidates, n=1)]
        hint = f"; did you mean {close[0]!r}?" if close else f" (known: {', '.join(sorted(known))})"
        raise InputError(f"{where}: unknown key {key!r} in {what}{hint}")


def json_depth(value):
    """Nesting depth of a parsed JSON value (iterative: no recursion limit)."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        v, d = stack.pop()
        if isinstance(v, (dict, list)):
            deepest = max(deepest, d)
            stack.extend((x, d + 1) for x in (v.values() if isinstance(v, dict) else v))
    return deepest


# -- files -------------------------------------------------------------------------------------

def regular_file_inside(path, folder, what, size_limit):
    """`path` resolved, if it is a regular file inside `folder` no larger than LIMITS[size_limit];
    else InputError. (A device or FIFO would be read forever; a file outside the scene's folder
    is not part of the scene.)"""
    path = Path(path)
    try:
        resolved = path.resolve()
        inside = resolved.is_relative_to(Path(folder).resolve())
    except (OSError, RuntimeError) as error:     # RuntimeError: a symlink loop
        raise InputError(f"{path}: cannot resolve the {what} path: {error}") from None
    if not inside:
        raise InputError(f"{path}: the {what} must be inside the scene folder {folder}")
    try:
        info = os.stat(resolved)
    except FileNotFoundError:
        raise InputError(f"{path}: {what} file not found") from None
    except OSError as error:
        raise InputError(f"{path}: cannot read the {what}: {error}") from None
    if not stat.S_ISREG(info.st_mode):
        raise InputError(f"{path}: the {what} is not a regular file")
    in_range(size_limit, max(info.st_size, 1), f"{path}: {what} size (bytes)")
    return resolved


def utf8_path(path, what):
    """`path` as a Path, if its name is valid UTF-8; else an InputError naming it. A file system
    allows any bytes in a name, but OpenImageIO (every image read or written), JSON reports and
    the printed summaries take only text: checked before any work, not after the render."""
    try:
        str(path).encode("utf-8")
    except UnicodeEncodeError:
        shown = os.fsencode(path).decode("utf-8", "backslashreplace")
        raise InputError(f"{what} {shown}: the path is not valid UTF-8; rename it or choose another") from None
    return Path(path)


def check_output(path):
    """Refuse an output image path before any work is done: it must end in .exr (an sRGB .png
    is written beside it) or .png (sRGB 8-bit only), must not be a folder, and its folder must
    accept a new file (tried with a temporary file that is removed at once)."""
    path = utf8_path(path, "--out")
    if path.suffix.lower() not in (".exr", ".png"):
        raise InputError(f"--out {path}: unsupported image type {path.suffix or '(none)'!r}; use .exr "
                         "(linear float, with an sRGB .png beside it) or .png (sRGB 8-bit)")
    return writable_file(path, "an image file")


def writable_file(path, what="a file", option="--out"):
    """`path` (the value of `option`) must not be a folder, and its folder must accept a new file:
    tried with a temporary file that is removed at once. Returns the Path; else an InputError."""
    path = utf8_path(path, option)
    if path.is_dir():
        raise InputError(f"{option} {path}: is a folder, not {what}")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path.parent, prefix=f".{path.name}.", suffix=".probe"):
            pass
    except OSError as error:
        raise InputError(f"{option} {path}: cannot write there: {error.strerror or error}") from None
    return path


def writable_folder(path, what="--out"):
    """`path` (a folder of outputs) can be made and written: tried with a temporary file that is
    removed at once. Returns the Path; else an InputError naming the problem."""
    path = utf8_path(path, what)
    if path.exists() and not path.is_dir():
        raise InputError(f"{what} {path}: is a file, not a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path, prefix=".toolkit-", suffix=".probe"):
            pass
    except OSError as error:
        raise InputError(f"{what} {path}: cannot write there: {error.strerror or error}") from None
    return path


# -- what a render needs -----------------------------------------------------------------------

def memory_bytes(width, height, spp):
    """Host and device bytes a render of width x height needs at most, estimated: the float64
    film (sum, sum of squares, pass sums, counts: ~13 numbers per pixel), the image and
    standard-error copies (6), float64 BDPT records per pass (3), and the float32 sample
    output of one pass (4 per pixel-sample of a pass, at least one sample per pixel)."""
    pixels = width * height
    return pixels * (8 * (13 + 6 + 3) + 16) + 16 * min(pixels * spp, max(pixels, 1 << 18))


def physical_memory():
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 16 << 30


def local_size(value, where="local_size"):
    """A work-group size the kernels are built and launched with: a power of two within
    LIMITS["technique.local_size"] (the kernels' scans and local arrays are sized by it)."""
    value = whole_number("technique.local_size", value, where)
    if value & (value - 1):
        raise InputError(f"{where} must be a power of two, got {value}")
    return value


def camera_size(width, height, spp=1):
    """(width, height) of a camera within LIMITS and within memory_bytes' estimate of what it
    needs (at `spp`), checked before anything is allocated for it: every command that allocates
    for a camera (render, crosscheck, bench --peer embree) asks this first."""
    width = whole_number("camera.width", width, "resolution width")
    height = whole_number("camera.height", height, "resolution height")
    need, have = memory_bytes(width, height, spp), physical_memory()
    if need > LIMITS["memory.fraction"][1] * have:
        raise InputError(f"resolution {width}x{height} needs about {need / 2**30:.1f} GiB for the film "
                         f"and buffers, more than half of this machine's {have / 2**30:.1f} GiB")
    return width, height
