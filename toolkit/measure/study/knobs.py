"""The study's runs (its curves): a technique, or a technique for each value of an accuracy knob
(`--knob max_depth=2,3,4,-1`), and what one repetition of a run needs on a worker."""
import dataclasses
from dataclasses import dataclass

from toolkit.api import _options
from toolkit.core.scene import check_scene
from toolkit.core.validate import InputError
from toolkit.measure.reference import reference_at, reference_problem
from toolkit.techniques import get_technique

DEFAULT_RESOLUTION = (32, 32)                  # every bundled reference averages down to it
INTEGRATOR_KNOBS = ("max_depth", "rr_depth", "clamp")   # scene integrator settings (FORMAT.md)


@dataclass(frozen=True)
class Run:
    """One curve of the study: a technique with its options, integrator settings and resolution."""
    label: str
    technique: str
    options: tuple = ()          # (name, value) pairs: technique options
    integrator: tuple = ()       # (name, value) pairs: overrides of the scene's integrator settings
    resolution: tuple = DEFAULT_RESOLUTION
    knob: tuple = None           # (name, value) for a knob sweep


@dataclass
class Repetition:
    """What a worker needs to render one repetition: nothing OpenCL, only names and numbers
    (a Dask worker makes its own context on its own device)."""
    scene: object                # scene folder (str), or a Scene made in Python (pickled)
    run: Run
    spp: int
    seed: int
    device: str = None
    bvh: str = "wide"


def parse_value(text):
    """A knob value from the command line: none/null, a whole number, a number, or a word."""
    text = text.strip()
    if text.lower() in ("none", "null", "off"):
        return None
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def parse_knob(text):
    """"max_depth=2,3,4,-1" -> ("max_depth", [2, 3, 4, -1]); resolution values are WxH."""
    if not isinstance(text, str) or "=" not in text:
        raise InputError(f"--knob must be NAME=V1,V2,... (like max_depth=2,3,4,-1), got {text!r}")
    name, values = text.split("=", 1)
    name = name.strip()
    items = [v for v in values.split(",") if v.strip()]
    if not items:
        raise InputError(f"--knob {name}: no values given")
    if name == "resolution":
        return name, [_resolution_value(v) for v in items]
    return name, [parse_value(v) for v in items]


def _resolution_value(text):
    try:
        w, h = (int(x) for x in str(text).lower().split("x"))
        if w >= 1 and h >= 1:
            return (w, h)
    except ValueError:
        pass
    raise InputError(f"--knob resolution: expected WIDTHxHEIGHT like 16x16, got {text!r}")


def make_runs(techniques, knob, resolution):
    """The study's curves: each technique, or each technique x knob value."""
    runs = []
    for name in techniques:
        cls, _ = get_technique(name)
        if knob is None:
            runs.append(Run(name, name, resolution=tuple(resolution)))
            continue
        knob_name, values = knob
        for value in values:
            runs.append(_knob_run(cls, name, knob_name, value, resolution))
    return runs


def _knob_run(cls, name, knob_name, value, resolution):
    """The run of technique `name` with one knob set to `value`."""
    label = f"{name} {knob_name}={'x'.join(map(str, value)) if knob_name == 'resolution' else value}"
    knob = (knob_name, value)
    if knob_name in INTEGRATOR_KNOBS:
        return Run(label, name, integrator=(knob,), resolution=tuple(resolution), knob=knob)
    if knob_name == "resolution":
        return Run(label, name, resolution=tuple(value), knob=knob)
    _options(cls, {knob_name: value})     # an option the technique takes, else a clear error
    return Run(label, name, options=(knob,), resolution=tuple(resolution), knob=knob)


def check_run(scene, run):
    """Before any work: the run's scene settings within limits and a reference to compare with."""
    if run.integrator:
        changed = dataclasses.replace(scene, **dict(run.integrator))
        for key, value in run.integrator:
            if key in ("max_depth", "rr_depth") and (isinstance(value, bool) or not isinstance(value, int)):
                raise InputError(f"knob {key} must be a whole number, got {value!r}")
        check_scene(changed, f"{scene.name} with {run.label}")
        if changed.max_depth < 0 and changed.rr_depth < 0:
            raise InputError(f"{run.label}: max_depth -1 (unbounded) needs Russian roulette (rr_depth >= 0)")
    width, height = run.resolution
    if reference_at(scene, width, height)[0] is None:
        raise InputError(f"{scene.name}: no reference to compare with at {width}x{height}: "
                         f"{reference_problem(scene, width, height) or 'the scene has none'}")
