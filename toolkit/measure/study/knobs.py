"""The study's runs (its curves): a technique, or a technique for each value of an accuracy knob
(`--knob max_depth=2,3,4,-1`), and what one repetition of a run needs on a worker."""
import dataclasses
import inspect
import math
from dataclasses import dataclass

from toolkit.api import _options
from toolkit.core.scene import check_scene
from toolkit.core.validate import LIMITS, InputError
from toolkit.measure.reference import reference_at, reference_problem
from toolkit.techniques import TECHNIQUES, get_technique

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
    scene: object                # absolute path of the scene file (str), or a Scene made in Python (pickled)
    run: Run
    spp: int
    seed: int
    device: str = None
    bvh: str = "wide"
    scene_digest: str = None     # workers.scene_digest of the scene the study loaded (with a path)


# The integrator knobs' types: (kind, whether "none" is a value).
INTEGRATOR_KINDS = {"max_depth": (int, False), "rr_depth": (int, False), "clamp": (float, True)}
TRUE, FALSE = ("true", "1"), ("false", "0")


def option_kind(name):
    """(kind, nullable) of the values of technique option `name`: the type of its default in the
    techniques' constructors (bool, int, float or str), else, where every default is None, that
    of its LIMITS row (whole numbers or not); nullable when a default is None (then "none" means
    the default). None for an option no technique takes (make_runs then names the known ones)."""
    defaults = [p.default for cls in TECHNIQUES.values() for c in cls.__mro__ if "__init__" in vars(c)
                for key, p in inspect.signature(c.__init__).parameters.items()
                if key == name and p.default is not p.empty]
    if not defaults:
        return None
    nullable = any(d is None for d in defaults)
    for default in defaults:
        if default is not None:
            return type(default), nullable
    lows = [low for key, (low, _, _) in LIMITS.items() if key.split(".")[0] in ("technique", "mlt")
            and key.split(".", 1)[1] == name]
    return (int if lows and isinstance(lows[0], int) else float if lows else str), nullable


def parse_value(text, kind, nullable, where):
    """One knob value from the command line as `kind` (bool: true/false/1/0; int; a finite
    float; str), or None for none/null when `nullable`; else an InputError naming `where`."""
    text = text.strip()
    if text.lower() in ("none", "null"):
        if nullable:
            return None
        raise InputError(f"{where}: {text!r} is not a value of this knob (it has no 'none')")
    if kind is bool:
        if text.lower() in TRUE + FALSE:
            return text.lower() in TRUE
        raise InputError(f"{where} takes true or false (or 1 or 0), got {text!r}")
    if kind in (int, float):
        try:
            value = kind(text)
        except ValueError:
            what = "a whole number" if kind is int else "a number"
            raise InputError(f"{where} takes {what}, got {text!r}") from None
        if kind is float and not math.isfinite(value):
            raise InputError(f"{where} takes a finite number, got {text!r}")
        return value
    return text


def parse_knob(text):
    """"max_depth=2,3,4,-1" -> ("max_depth", [2, 3, 4, -1]): each value parsed with the knob's own
    type (option_kind, INTEGRATOR_KINDS: coalesced_scatter=false is False, not the true string
    'false'); resolution values are WxH."""
    if not isinstance(text, str) or "=" not in text:
        raise InputError(f"--knob must be NAME=V1,V2,... (like max_depth=2,3,4,-1), got {text!r}")
    name, values = text.split("=", 1)
    name = name.strip()
    items = [v for v in values.split(",") if v.strip()]
    if not items:
        raise InputError(f"--knob {name}: no values given")
    if name == "resolution":
        return name, [_resolution_value(v) for v in items]
    kind = INTEGRATOR_KINDS.get(name) or option_kind(name)
    if kind is None:
        return name, [v.strip() for v in items]     # no technique takes it: make_runs says so
    return name, [parse_value(v, *kind, f"--knob {name}") for v in items]


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
    shown = "x".join(map(str, value)) if knob_name == "resolution" else _shown(value)
    label = f"{name} {knob_name}={shown}"
    knob = (knob_name, value)
    if knob_name in INTEGRATOR_KNOBS:
        return Run(label, name, integrator=(knob,), resolution=tuple(resolution), knob=knob)
    if knob_name == "resolution":
        return Run(label, name, resolution=tuple(value), knob=knob)
    _options(cls, {knob_name: value})     # an option the technique takes, else a clear error
    return Run(label, name, options=(knob,), resolution=tuple(resolution), knob=knob)


def _shown(value):
    """A knob value as a label shows it: 2.0 as 2 (clamp=2), every other float in full."""
    return repr(value).removesuffix(".0") if isinstance(value, float) else str(value)


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
