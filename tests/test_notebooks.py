"""The tutorials in tutorials/ run from top to bottom without error, in their fast mode.

Each notebook checks its own results with asserts, so executing it is the test. Where the
documentation's packages are installed (the test extras bring them), the site's build in
tests/test_docs.py executes them, so that each runs once in the suite; the test here runs them
only without those packages. Notebooks are committed without outputs: a stored output would go
stale as the toolkit changes (and bloat the diff), so the second test rejects any.
"""
import importlib.util
import json
import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
TUTORIALS = ROOT / "tutorials"
NOTEBOOKS = sorted(TUTORIALS.glob("*.ipynb"))
CELL_TIMEOUT = 300  # seconds per cell
ANSI_ESCAPE = re.compile(r"\x1b\[[0-9;]*m")


def test_tutorials_folder_holds_notebooks():
    assert NOTEBOOKS, f"no notebooks in {TUTORIALS}"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_has_no_outputs(path):
    nb = json.loads(path.read_text(encoding="utf-8"))
    assert nb.get("nbformat") == 4, f"{path.name}: not an nbformat v4 notebook"
    stored = [i for i, cell in enumerate(nb["cells"]) if cell["cell_type"] == "code"
              and (cell.get("outputs") or cell.get("execution_count") is not None)]
    assert not stored, (f"{path.name}: code cells {stored} carry outputs or execution counts; "
                        "clear them before committing (Jupyter: Edit > Clear All Outputs)")


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_cells_hold_no_control_characters(path):
    """A LaTeX command written in a Python string ("\\frac" as "\frac") turns into a control
    character (form feed, bell, tab, ...) and the formula renders as garbage; newlines are fine."""
    nb = json.loads(path.read_text(encoding="utf-8"))
    found = []
    for i, cell in enumerate(nb["cells"]):
        source = "".join(cell["source"]) if isinstance(cell["source"], list) else cell["source"]
        found += [(i, repr(ch)) for ch in sorted(set(source)) if ord(ch) < 32 and ch != "\n"]
    assert not found, f"{path.name}: (cell, control character) {found}; write the backslash twice"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_runs_and_its_checks_pass(path, python3_kernel, monkeypatch):
    if all(importlib.util.find_spec(name) for name in ("sphinx", "myst_nb", "furo")):
        pytest.skip("executed by the documentation's build (tests/test_docs.py)")
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    # The kernel inherits this environment: fast mode, no display, and the toolkit under test
    # (the checkout this file belongs to) ahead of any installed copy.
    monkeypatch.setenv("TOOLKIT_FAST_NOTEBOOKS", "1")
    monkeypatch.setenv("TOOLKIT_NOTEBOOK_HEADLESS", "1")      # the live demo's widget: a few frames, then a still
    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        [str(ROOT)] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
    nb = nbformat.read(path, as_version=4)
    client = nbclient.NotebookClient(nb, timeout=CELL_TIMEOUT, kernel_name=python3_kernel,
                                     resources={"metadata": {"path": str(TUTORIALS)}})
    failure = None
    try:
        client.execute()
    except nbclient.exceptions.CellExecutionError as error:
        failure = ANSI_ESCAPE.sub("", str(error))   # the kernel's traceback is coloured
    if failure is not None:
        pytest.fail(f"{path.name}: a cell failed\n{failure}", pytrace=False)
