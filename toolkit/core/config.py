"""The toolkit's configuration: its settings from environment variables, read in this one place.

`config()` reads the environment each time it is called (a few dictionary look-ups), so a
change made before a call counts, and nothing is kept between calls. A value that is not one of
the allowed ones is an InputError that names the variable: the command line shows it as one
`error:` line. (The live demo's Settings, toolkit/demo/settings.py, are something else: the
scene, techniques and size a learner picks in the demo's page.)

The toolkit's own variables:

| variable                    | Config field        | meaning                                                 |
|-----------------------------|---------------------|---------------------------------------------------------|
| `TOOLKIT_CACHE_DIR`         | `cache_dir`         | pyopencl's binary-cache folder for kernel builds (default: pyopencl's own, toolkit/opencl/kernel_cache.py) |
| `TOOLKIT_HIDE_PLATFORMS`    | `hide_platforms`    | comma-separated parts of platform names whose devices count as unusable (toolkit/opencl/device.py) |
| `TOOLKIT_LANES`             | `lanes`             | `on` or `off`: work-items as SIMD lanes on Intel's CPU runtime, where the toolkit chooses (toolkit/opencl/lanes.py; default off) |
| `TOOLKIT_NO_PIP_RUNTIMES`   | `no_pip_runtimes`   | `1`: do not register pip's OpenCL runtimes with the loader (toolkit/opencl/runtimes.py) |
| `TOOLKIT_VERBOSE`           | `verbose`           | `1`: print every kernel build's log (as `--verbose` does) |
| `TOOLKIT_WERROR`            | `werror`            | `1`: a compiler warning fails the build (the test suite sets it) |
| `TOOLKIT_NOTEBOOK_HEADLESS` | `notebook_headless` | `1`: nobody watches the notebook; the live demo's widget renders a few frames, then a still (toolkit/demo/) |
| `TOOLKIT_FAST_NOTEBOOKS`    | `fast_notebooks`    | `0`: the tutorials' larger settings; default `1`, small and fast (tutorials/*.ipynb) |
| `TOOLKIT_DOCS_EXECUTION`    | (the docs build's)  | how the docs' build runs the notebooks: myst-nb's `nb_execution_mode` (docs/conf.py; default `cache`) |

Yes/no variables take `1` or `0` (unset or empty: the default). Other programs' variables that
the toolkit reads, never sets here:

| variable                        | Config field        | why                                                  |
|---------------------------------|---------------------|------------------------------------------------------|
| `PYOPENCL_CTX`                  | `pyopencl_ctx`      | pyopencl's device choice, honoured by `get_queue` when no device is given |
| `CL_CONFIG_USE_VECTORIZER`      | `intel_use_vectorizer` | Intel's vectorizer switch, which fixes lanes for the whole process (lanes.py) |
| `CL_CONFIG_CPU_VECTORIZER_MODE` | `intel_vectorizer_mode` | the same, by mode (1: off)                        |
| `USERNAME`                      | `user_name`         | names this user's private folders where there is no user id (Windows) |

What the toolkit writes into the environment, for the OpenCL loader, pyopencl and PoCL to read
(OCL_ICD_VENDORS, PYOPENCL_NO_CACHE, POCL_CACHE_DIR, ...), is done in toolkit/opencl/runtimes.py
and toolkit/opencl/windows_runtime.py, before the first OpenCL call.
"""
import os
from dataclasses import dataclass

from toolkit.core.errors import InputError

LANES = ("on", "off")
YES_NO = {"1": True, "0": False}


@dataclass(frozen=True)
class Config:
    """Every variable of the tables in the module's docstring, parsed."""
    cache_dir: str = None
    hide_platforms: tuple = ()
    lanes: str = None
    no_pip_runtimes: bool = False
    verbose: bool = False
    werror: bool = False
    notebook_headless: bool = False
    fast_notebooks: bool = True
    pyopencl_ctx: str = None
    intel_use_vectorizer: str = None
    intel_vectorizer_mode: str = None
    user_name: str = None


def checked_lanes(value, what="lanes"):
    """None, "on" or "off" (the values of TOOLKIT_LANES and of every lanes option); anything else an
    InputError that names `what`."""
    if value is None or value in LANES:
        return value
    raise InputError(f"{what} must be 'on' or 'off', got {value!r}")


def config(environ=None):
    """The Config of `environ` (default: this process's environment, read now)."""
    environ = os.environ if environ is None else environ

    def text(name):
        return environ.get(name) or None   # set but empty counts as unset

    def yes_no(name, default):
        value = text(name)
        if value is None:
            return default
        if value.strip() not in YES_NO:
            raise InputError(f"{name} must be 1 or 0, got {value!r}")
        return YES_NO[value.strip()]

    lanes = checked_lanes(text("TOOLKIT_LANES"), "TOOLKIT_LANES")
    hidden = tuple(part.strip().lower() for part in (text("TOOLKIT_HIDE_PLATFORMS") or "").split(",") if part.strip())
    return Config(cache_dir=text("TOOLKIT_CACHE_DIR"), hide_platforms=hidden, lanes=lanes,
                    no_pip_runtimes=yes_no("TOOLKIT_NO_PIP_RUNTIMES", False), verbose=yes_no("TOOLKIT_VERBOSE", False),
                    werror=yes_no("TOOLKIT_WERROR", False), notebook_headless=yes_no("TOOLKIT_NOTEBOOK_HEADLESS", False),
                    fast_notebooks=yes_no("TOOLKIT_FAST_NOTEBOOKS", True), pyopencl_ctx=text("PYOPENCL_CTX"),
                    intel_use_vectorizer=environ.get("CL_CONFIG_USE_VECTORIZER"),
                    intel_vectorizer_mode=text("CL_CONFIG_CPU_VECTORIZER_MODE"), user_name=text("USERNAME"))


def environment_copy():
    """A copy of this process's whole environment, for a child process's (toolkit/grading/limits.py
    keeps a part of it for the grader's worker)."""
    return dict(os.environ)
