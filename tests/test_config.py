"""The toolkit's configuration (toolkit/core/config.py): every variable it documents is parsed,
a bad value is an error that names the variable, and nothing else in toolkit/ reads the
environment (the OpenCL runtime registration, which writes it for the loader, aside)."""
import re
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import pytest

from toolkit.core import config as config_module
from toolkit.core.config import Config, config
from toolkit.core.validate import InputError

ROOT = Path(__file__).resolve().parent.parent

EVERY_ONE_SET = {
    "TOOLKIT_CACHE_DIR": "/somewhere/cache", "TOOLKIT_HIDE_PLATFORMS": " Portable, ,Oclgrind ",
    "TOOLKIT_LANES": "on", "TOOLKIT_NO_PIP_RUNTIMES": "1", "TOOLKIT_VERBOSE": "1", "TOOLKIT_WERROR": "1",
    "TOOLKIT_NOTEBOOK_HEADLESS": "1", "TOOLKIT_FAST_NOTEBOOKS": "0", "PYOPENCL_CTX": "0:1",
    "CL_CONFIG_USE_VECTORIZER": "False", "CL_CONFIG_CPU_VECTORIZER_MODE": "1", "USERNAME": "ada",
}


def test_every_variable_is_parsed_into_its_field():
    assert config(EVERY_ONE_SET) == Config(
        cache_dir="/somewhere/cache", hide_platforms=("portable", "oclgrind"), lanes="on", no_pip_runtimes=True,
        verbose=True, werror=True, notebook_headless=True, fast_notebooks=False, pyopencl_ctx="0:1",
        intel_use_vectorizer="False", intel_vectorizer_mode="1", user_name="ada")


def test_unset_and_empty_variables_give_the_defaults():
    assert config({}) == Config()
    assert config({name: "" for name in EVERY_ONE_SET}) == Config(intel_use_vectorizer="")
    assert Config().fast_notebooks and not Config().werror and Config().lanes is None


def test_every_field_and_every_variable_is_documented_once():
    """The module's docstring is the one list: each field in it, each TOOLKIT_ variable of the
    toolkit, its tutorials and its docs build in it exactly once as a table row."""
    doc = config_module.__doc__
    for f in fields(Config):
        assert f"`{f.name}`" in doc, f.name
    used = set()
    for folder in ("toolkit", "tutorials", "docs", "tests"):
        for path in (ROOT / folder).rglob("*"):
            if path.suffix in (".py", ".ipynb", ".md") and "_build" not in path.parts:
                used |= set(re.findall(r"\bTOOLKIT_[A-Z_]*[A-Z]\b", path.read_text(encoding="utf-8")))
    used.discard("TOOLKIT_PARENT")   # grading/runner.py's constant, not a variable
    rows = re.findall(r"^\| `(TOOLKIT_[A-Z_]+)`", doc, re.M)
    assert sorted(rows) == sorted(set(rows)) and set(rows) == used, (sorted(rows), sorted(used))


@pytest.mark.parametrize("name, value, message", [
    ("TOOLKIT_LANES", "sideways", "TOOLKIT_LANES must be 'on' or 'off', got 'sideways'"),
    ("TOOLKIT_WERROR", "yes", "TOOLKIT_WERROR must be 1 or 0, got 'yes'"),
    ("TOOLKIT_NO_PIP_RUNTIMES", "true", "TOOLKIT_NO_PIP_RUNTIMES must be 1 or 0, got 'true'"),
    ("TOOLKIT_VERBOSE", "2", "TOOLKIT_VERBOSE must be 1 or 0, got '2'"),
    ("TOOLKIT_NOTEBOOK_HEADLESS", "on", "TOOLKIT_NOTEBOOK_HEADLESS must be 1 or 0, got 'on'"),
    ("TOOLKIT_FAST_NOTEBOOKS", "fast", "TOOLKIT_FAST_NOTEBOOKS must be 1 or 0, got 'fast'")])
def test_a_bad_value_is_an_error_that_names_the_variable(name, value, message):
    with pytest.raises(InputError, match=re.escape(message)):
        config({name: value})


def test_it_reads_the_environment_when_asked(monkeypatch):
    """Nothing is kept between calls: a change to the environment counts at the next call."""
    monkeypatch.setenv("TOOLKIT_HIDE_PLATFORMS", "intel")
    assert config().hide_platforms == ("intel",)
    monkeypatch.delenv("TOOLKIT_HIDE_PLATFORMS")
    assert config().hide_platforms == ()


def test_only_the_config_and_the_runtime_registration_touch_the_environment():
    """The toolkit reads its settings in core/config.py; runtimes.py and windows_runtime.py
    write what the OpenCL loader, pyopencl and PoCL read. No other file names os.environ (or
    os.getenv / os.putenv)."""
    allowed = {"toolkit/core/config.py", "toolkit/opencl/runtimes.py", "toolkit/opencl/windows_runtime.py"}
    found = {path.relative_to(ROOT).as_posix() for path in (ROOT / "toolkit").rglob("*.py")
             if re.search(r"\bos\.(environ|getenv|putenv)\b", path.read_text(encoding="utf-8"))}
    assert found <= allowed, sorted(found - allowed)
    assert "toolkit/core/config.py" in found     # the search itself finds what it looks for


def test_a_bad_value_stops_a_command_with_one_line():
    run = subprocess.run([sys.executable, "-m", "toolkit", "render", "--spp", "1", "--resolution", "8x8"],
                         cwd=ROOT, capture_output=True, text=True, timeout=300,
                         env={**config_module.environment_copy(), "TOOLKIT_WERROR": "yes"})
    assert run.returncode == 2 and "Traceback" not in run.stderr, run.stderr
    assert "TOOLKIT_WERROR must be 1 or 0, got 'yes'" in run.stderr
