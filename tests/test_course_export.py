"""`python -m toolkit course export` (toolkit/grading/export.py): the student edition holds no
solution, anywhere (its toolkit copy, docs and notebooks included); the instructor edition holds
them all; the student edition's stubs build, and whatever needs an unwritten one says so."""
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from xml.etree import ElementTree

import pytest

from toolkit.cli import main
from toolkit.grading.checks import ASSIGNMENTS
from toolkit.grading.edition import STUDENT_SOURCES
from toolkit.grading.export import export

ROOT = Path(__file__).resolve().parent.parent
_DEFINITION = re.compile(r"\b(\w+)\s*\([^;{}()]*\)\s*\{")   # parameters hold no parentheses
_COMMENT = re.compile(r"/\*.*?\*/|//[^\n]*", re.S)


def _functions(text):
    """{name: body} of every C function defined in `text` (the body between its braces, without
    comments: the search below compares text without comments too)."""
    # a comment that says TODO leaves the word in the body (the stub's mark of what is to write)
    text = _COMMENT.sub(lambda m: " TODO " if "TODO" in m.group(0) else " ", text)
    text = re.sub(r"^\s*#.*$", "", text, flags=re.M)   # nor preprocessor lines
    out = {}
    for match in _DEFINITION.finditer(text):
        if match.group(1) in ("if", "for", "while", "switch"):
            continue
        depth, i = 1, match.end()
        while depth:
            depth += {"{": 1, "}": -1}.get(text[i], 0)
            i += 1
        out.setdefault(match.group(1), text[match.end():i - 1])
    return out


def _squeezed(text):
    """`text` without C comments, preprocessor lines and whitespace, as _functions gives a body: a
    body is found however it is laid out or commented."""
    return re.sub(r"\s+", "", re.sub(r"^\s*#.*$", "", _COMMENT.sub(" ", text), flags=re.M))


def solution_bodies():
    """{(assignment, function): the solution's body} of every function whose stub body says TODO."""
    bodies = {}
    for a in ASSIGNMENTS.values():
        stub = _functions((ROOT / "tutorials/assignments" / a.name / a.stub).read_text())
        solution = _functions((ROOT / "cl" / a.replaces).read_text())
        for name, body in stub.items():
            if "TODO" in body:
                assert name in solution, f"{a.name}: the stub's {name} is not in cl/{a.replaces}"
                bodies[(a.name, name)] = solution[name]
    return bodies


def _texts(folder):
    """(relative path, text) of every text file under `folder`; a notebook's cells and outputs as text."""
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue   # images, EXR, meshes in binary
        if path.suffix == ".ipynb":
            cells = json.loads(text)["cells"]
            text = "\n".join(["".join(c["source"]) for c in cells] + [json.dumps(c.get("outputs", []))
                                                                      for c in cells]
                             + ["".join(o.get("text", "")) for c in cells for o in c.get("outputs", [])])
        yield str(path.relative_to(folder)), text


def found_bodies(folder):
    """{(assignment, function): [files holding its solution body]} in `folder`."""
    bodies = solution_bodies()
    found = {}
    for name, text in _texts(folder):
        squeezed = _squeezed(text)
        for key, body in bodies.items():
            if _squeezed(body) in squeezed:
                found.setdefault(key, []).append(name)
    return found


@pytest.fixture(scope="module")
def editions(tmp_path_factory):
    root = tmp_path_factory.mktemp("course")
    export(root / "student")
    export(root / "instructor", instructor=True)
    return root / "student", root / "instructor"


def test_the_student_edition_holds_no_solution_body(editions):
    student, instructor = editions
    bodies = solution_bodies()
    # every stub leaves something to write: compaction 2, parallel_connect 3, mis 1, inplace_regen 1 (today)
    assert {a for a, _ in bodies} == set(ASSIGNMENTS)
    assert found_bodies(student) == {}
    assert not (student / "tests/fixtures").exists() and not (student / "docs/instructor_guide.md").exists()
    assert not [name for name, text in _texts(student / "docs") if "instructor_guide" in text]   # nor a link to it
    assert not (student / "docs/gradescope.md").exists()   # the Gradescope page: the instructor's too
    assert not [name for name, text in _texts(student / "docs") if "gradescope.md" in text or "\ngradescope\n" in text]
    assert "instructor_guide" in (instructor / "docs/course.md").read_text()
    quick_start = lambda readme: readme.split("## Quick start")[1].split("```")[1]   # the two commands
    assert quick_start((student / "README.md").read_text()) == quick_start((ROOT / "README.md").read_text())
    # the one line that marks the edition (toolkit/grading/edition.py); the checkout's says "not the student's"
    marked = f'DEFAULT_SOURCES = "{STUDENT_SOURCES}"'
    assert marked in (student / "toolkit/opencl/program.py").read_text()
    assert marked not in (instructor / "toolkit/opencl/program.py").read_text()
    # the docs' pages include these parts of the README: the student's README has them too
    from toolkit.grading.export import README_MARKS
    for mark in README_MARKS:
        assert mark in (ROOT / "README.md").read_text() and mark in (student / "README.md").read_text(), mark
    for name in ("docs/index.md", "docs/getting_started.md"):
        includes = re.findall(r':(?:start-after|end-before): "([^"]+)"', (student / name).read_text())
        assert includes and set(includes) <= set(README_MARKS), (name, includes)


def test_the_search_finds_them_where_they_are(editions, tmp_path):
    """The test above can fail: the same search finds every body in the instructor edition and in the
    checkout, and one planted in a notebook's output, reformatted."""
    _, instructor = editions
    bodies = solution_bodies()
    assert set(found_bodies(instructor)) == set(bodies)
    in_checkout = found_bodies(ROOT)
    assert set(in_checkout) == set(bodies) and all(f"cl/{ASSIGNMENTS[a].replaces}" in in_checkout[a, function]
                                                   for a, function in bodies)
    # the wrong-kernel fixtures are the solutions with one bug each: most hold a solution's body
    assert any(f.startswith("tests/fixtures/assignments/") for files in in_checkout.values() for f in files)
    (assignment, function), body = next(iter(bodies.items()))
    planted = {"cells": [{"cell_type": "code", "source": "print(x)", "metadata": {},
                          "outputs": [{"output_type": "stream", "name": "stdout",
                                       "text": " \n   ".join(body.split())}]}]}
    (tmp_path / "n.ipynb").write_text(json.dumps(planted))
    assert found_bodies(tmp_path) == {(assignment, function): ["n.ipynb"]}


def test_the_student_edition_has_each_stub_in_its_solutions_place(editions):
    student, instructor = editions
    for a in ASSIGNMENTS.values():
        stub = (ROOT / "tutorials/assignments" / a.name / a.stub).read_text()
        assert (student / "cl" / a.replaces).read_text() == stub
        assert (instructor / "cl" / a.replaces).read_text() == (ROOT / "cl" / a.replaces).read_text()
    assert (instructor / "tests/fixtures/assignments").is_dir()
    assert sorted(p.name for p in (student / "tests").iterdir()) == ["test_my_assignments.py"]


def _in(folder, code, timeout=300):
    """Run Python `code` in `folder` (its toolkit and cl/, not this checkout's)."""
    env = dict(os.environ, PYTHONPATH=str(folder))
    return subprocess.run([sys.executable, "-c", code], cwd=folder, env=env, capture_output=True, text=True,
                          timeout=timeout)


def test_the_student_editions_stubs_build_and_a_technique_says_what_it_needs(editions):
    student, _ = editions
    built = _in(student, """
from toolkit.core.scene import bundled_scene_dir, load_scene
from toolkit.grading import stubs
from toolkit.opencl import program
from toolkit.opencl.device import get_queue
from toolkit.opencl.device_scene import DeviceScene
from toolkit.techniques import BdptParallelConnect, PtCompactRegen, PtInplaceRegen
assert str(program.cl_dir()).startswith(%r)
queue = get_queue()
scene = DeviceScene(queue, load_scene(bundled_scene_dir("cornell_box")))
try:
    PtCompactRegen(queue, scene)
    raise SystemExit("built from an untouched stub without a word")
except stubs.AssignmentNotWritten as error:
    print(error)
as_they_are = stubs.CourseSources(refused=set())   # build them all as they are: every stub must compile
for cls in (PtCompactRegen, PtInplaceRegen, BdptParallelConnect):
    cls(queue, scene, sources=as_they_are)
print("built")
""" % str(student))
    assert built.returncode == 0, built.stderr[-3000:]
    assert "cl/compact.h is still the stub of assignment `compaction`" in built.stdout
    assert built.stdout.strip().endswith("built")


def test_export_into_a_folder_that_is_not_empty_is_refused(tmp_path, capsys):
    (tmp_path / "x").write_text("mine")
    assert main(["course", "export", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "not an empty folder" in err and "Traceback" not in err
    assert (tmp_path / "x").read_text() == "mine" and len(list(tmp_path.iterdir())) == 1


def test_the_student_editions_public_checks_give_a_right_solution_every_point_they_grade(editions, tmp_path):
    """A student who writes each file right loses no point in their copy: the public checks that run
    there use nothing the student edition lacks (another assignment's file is a stub there)."""
    student, _ = editions
    mine = tmp_path / "mine"
    shutil.copytree(student, mine)
    for a in ASSIGNMENTS.values():
        shutil.copyfile(ROOT / "cl" / a.replaces, mine / "cl" / a.replaces)
    report = tmp_path / "report.xml"
    tests = _in(mine, "import sys, pytest; sys.exit(pytest.main(['-q', '-n', '0', '-p', 'no:cacheprovider', "
                      f"'--junitxml={report}', '-o', 'junit_family=xunit1', 'tests/test_my_assignments.py']))", timeout=600)
    assert tests.returncode == 0, tests.stdout[-3000:] + tests.stderr[-2000:]
    assert f"{len(ASSIGNMENTS)} passed" in tests.stdout
    # The checks it skipped because they compare with the reference solution are the ones marked
    # hidden (Check.hidden): the Gradescope autograder shows them as the instructor chose.
    skipped = {case.get("name").split("[")[1].rstrip("]"): set(prop.get("value").split())
               for case in ElementTree.parse(report).iter("testcase")
               for prop in case.iter("property") if prop.get("name") == "instructor_checks"}
    assert skipped == {name: {c.name for c in a.checks if c.hidden} for name, a in ASSIGNMENTS.items()}


def test_the_student_editions_notebooks_run_and_say_what_they_need(editions, python3_kernel, monkeypatch):
    """Each notebook of the student edition runs from top to bottom on the student's toolkit (its
    stubs in cl/, its exercises not written): a cell that needs an unwritten assignment or exercise
    prints `not run: ...` and the notebook goes on (toolkit/grading/notebooks.py). A cell that
    fails for another reason before that fails the test."""
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    student, _ = editions
    monkeypatch.setenv("TOOLKIT_FAST_NOTEBOOKS", "1")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.setenv("PYTHONPATH", str(student))   # the student's toolkit, not this checkout's
    paths = sorted((student / "tutorials").glob("*.ipynb"))
    assert [p.name for p in paths] == [p.name for p in sorted((ROOT / "tutorials").glob("*.ipynb"))]
    for path in paths:
        nb = nbformat.read(path, as_version=4)
        # a last cell that says whose cl/ the notebook built from
        nb.cells.append(nbformat.v4.new_code_cell("from toolkit.opencl.program import cl_dir\nprint('cl:', cl_dir())"))
        client = nbclient.NotebookClient(nb, timeout=300, kernel_name=python3_kernel,
                                         resources={"metadata": {"path": str(path.parent)}})
        try:
            client.execute()
        except nbclient.exceptions.CellExecutionError as error:
            traceback = re.sub(r"\x1b\[[0-9;]*m", "", str(error))   # the kernel's traceback is coloured
            pytest.fail(f"student edition's {path.name}: a cell failed\n{traceback}", pytrace=False)
        printed = "".join(out.get("text", "") for cell in nb.cells if cell.cell_type == "code"
                          for out in cell.get("outputs", []) if out.get("output_type") == "stream")
        assert f"cl: {student / 'cl'}" in printed, (path.name, printed[-500:])
        # every notebook uses an assignment or holds an exercise: the mechanism ran, no solution did
        assert "not run: " in printed, path.name
