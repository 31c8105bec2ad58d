"""Sphinx configuration of the toolkit's site. Build: python -m sphinx -W -b html docs docs/_build/html

The tutorials are executed during the build, in their fast mode, by myst-nb; their asserts are
the suite's notebook test (tests/test_docs.py), so the suite executes them once, here.
"""
import filecmp
import json
import os
import shutil
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path[:0] = [str(ROOT), str(DOCS / "_ext")]          # the checkout's toolkit, and our extension

# The notebooks' kernels inherit this environment: fast mode, the checkout's toolkit, and
# matplotlib's inline backend (an MPLBACKEND of Agg would show no figures).
os.environ.setdefault("TOOLKIT_FAST_NOTEBOOKS", "1")
# No one watches a notebook the build runs: the live demo's widget renders a few frames and shows a still.
os.environ["TOOLKIT_NOTEBOOK_HEADLESS"] = "1"
os.environ["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in [os.environ.get("PYTHONPATH")] if p])
os.environ.pop("MPLBACKEND", None)
# A "python3" kernel that runs this interpreter, ahead of any kernelspec of the user's that
# might run another one (JUPYTER_PATH comes first).
KERNELS = DOCS / "_build" / "jupyter"
(KERNELS / "kernels" / "python3").mkdir(parents=True, exist_ok=True)
(KERNELS / "kernels" / "python3" / "kernel.json").write_text(json.dumps({
    "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
    "display_name": "Python 3 (the toolkit's docs)", "language": "python"}))
os.environ["JUPYTER_PATH"] = os.pathsep.join([str(KERNELS)] + [p for p in [os.environ.get("JUPYTER_PATH")] if p])


def copy_into_docs(source, pattern):
    """Copy the checkout's files (the notebooks, the handouts, the results) into docs/, where
    Sphinx wants its pages; a copy, not a link, because Sphinx resolves links to their real
    path and would then not find the pages they link to. Unchanged files keep their copy, so
    an unchanged notebook keeps its cached outputs."""
    for path in sorted((ROOT / source).glob(pattern)):
        copy = DOCS / source / path.relative_to(ROOT / source)
        if not (copy.exists() and filecmp.cmp(path, copy, shallow=False)):
            copy.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, copy)


# docs/tutorials/, docs/results/: generated (.gitignore). A notebook runs in docs/tutorials/, where
# its "../scenes" is docs/scenes, a link to the checkout's scenes/ (Sphinx does not read it).
copy_into_docs("tutorials", "*.ipynb")
copy_into_docs("tutorials", "assignments/**/*.md")
copy_into_docs("results", "*.md")


def demo_screenshot():
    """docs/demo.md shows the live demo's screenshot, which tests/test_demo_browser.py takes into
    docs/_build/demo.png (not committed: it is remade by every run of the test). The page includes
    docs/_build/demo_screenshot.md, written here: the image where it exists, else a line saying how
    to make it, so that a build without it has no missing image (and no warning under -W)."""
    build = DOCS / "_build"
    build.mkdir(exist_ok=True)
    if (build / "demo.png").is_file():
        text = ("![The demo in headless chromium: three path tracers side by side, their SIMD efficiency beside "
                "the talk's, the lanes of four warps per technique, and the image means over time](demo.png)\n")
    else:
        text = ("*No screenshot in this build: `python -m pytest tests/test_demo_browser.py` takes it "
                "(into docs/_build/demo.png), and the next build shows it here.*\n")
    (build / "demo_screenshot.md").write_text(text, encoding="utf-8")


demo_screenshot()

project = "SIMD-efficient light transport toolkit"
author = "the toolkit's authors"
extensions = ["myst_nb", "sphinx.ext.autodoc", "sphinx.ext.napoleon", "toolkit_docs"]
html_theme = "furo"          # PyOpenCL's theme
html_title = "SIMD light transport toolkit"
exclude_patterns = ["_build", "scenes", "**/.ipynb_checkpoints"]
myst_enable_extensions = ["colon_fence", "dollarmath"]
myst_heading_anchors = 3

# "cache" keeps outputs between builds of unchanged notebooks (jupyter-cache, in docs/_build);
# the suite asks for "force" so that the toolkit's code, not a cache, makes every output.
nb_execution_mode = os.environ.get("TOOLKIT_DOCS_EXECUTION", "cache")
nb_execution_timeout = 300           # seconds per cell, as the notebooks' test had
nb_execution_raise_on_error = True   # a failed assert in a tutorial fails the build
nb_execution_show_tb = True
nb_merge_streams = True

autodoc_member_order = "bysource"
autodoc_default_options = {"members": True}
