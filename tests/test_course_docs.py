"""The course's pages keep up with the grader: the instructor guide (docs/instructor_guide.md)
names every check with its points and every wrong-kernel fixture, the syllabus (docs/syllabus.md)
every notebook and assignment, and the handouts, their index and the course page list the
assignments in the order of ASSIGNMENTS, which is the talk's."""
import re
import shlex
from pathlib import Path

import pytest

from toolkit.grading.checks import ASSIGNMENTS
from toolkit.techniques import TECHNIQUES, VARIANTS

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
HANDOUTS = ROOT / "tutorials" / "assignments"
FIXTURES = ROOT / "tests" / "fixtures" / "assignments"
NOTEBOOKS = sorted(p.name for p in (ROOT / "tutorials").glob("*.ipynb"))


def read(path):
    return path.read_text(encoding="utf-8")


def section(text, heading):
    """The text under markdown heading `heading` (a whole line), up to the next heading of the same
    or a higher level."""
    lines = text.splitlines()
    start = lines.index(heading) + 1   # ValueError: no such heading
    level = len(heading) - len(heading.lstrip("#"))
    end = next((i for i in range(start, len(lines))
                if re.match(r"#{1,%d} " % level, lines[i])), len(lines))
    return "\n".join(lines[start:end])


def guide_section(position, name):
    return section(read(DOCS / "instructor_guide.md"), f"## {position}. `{name}`")


@pytest.mark.parametrize("position,name", list(enumerate(ASSIGNMENTS, start=1)))
def test_instructor_guide_gives_every_check_with_its_points(position, name):
    text = guide_section(position, name)
    rows = dict(re.findall(r"^\| `(\w+)` \| (\d+) \|", text, re.M))
    assert rows == {c.name: str(c.points) for c in ASSIGNMENTS[name].checks}


@pytest.mark.parametrize("position,name", list(enumerate(ASSIGNMENTS, start=1)))
def test_instructor_guide_names_every_fixture_with_its_score(position, name):
    text = guide_section(position, name)
    named = set(re.findall(r"^\*\*`(\w+)\.cl`: \d+/100\.\*\*", text, re.M))
    assert named == {p.stem for p in (FIXTURES / name).glob("*.cl")}


def test_every_fixture_folder_is_an_assignment():
    # a fixture folder of an assignment that ASSIGNMENTS lacks would escape the guide's tests above
    assert {p.name for p in FIXTURES.iterdir() if p.is_dir()} <= set(ASSIGNMENTS)


def test_syllabus_names_every_notebook_and_assignment():
    text = read(DOCS / "syllabus.md")
    weeks, hours = section(text, "## The weeks"), section(text, "## Student hours")
    for part in (weeks, hours):
        assert [n for n in NOTEBOOKS if f"`{n}`" not in part] == []
        assert [a for a in ASSIGNMENTS if f"`{a}`" not in part] == []
    # the weeks take the assignments in the course's order
    firsts = [weeks.index(f"`{a}`") for a in ASSIGNMENTS]
    assert firsts == sorted(firsts)



def test_syllabus_counts_each_notebooks_words_and_cells_and_its_hours_follow_from_them():
    """The hours table counts each notebook's prose (to the nearest hundred words) and its code
    cells, and estimates its hours from them at the rates it gives (100 words a minute, 5 minutes
    a code cell, rounded to the half hour): a notebook that grows must be counted again."""
    import json
    hours = section(read(DOCS / "syllabus.md"), "## Student hours")
    for name in NOTEBOOKS:
        row = re.search(r"^\| \[`" + re.escape(name) + r"`\][^|]*\| ([\d,]+) words[^,|]*, (\d+) code cells \| ([\d.]+) \|$",
                        hours, re.M)
        assert row, f"no hours row for {name}"
        cells = json.loads((ROOT / "tutorials" / name).read_text())["cells"]
        words = sum(len("".join(c["source"]).split()) for c in cells if c["cell_type"] == "markdown")
        code = sum(c["cell_type"] == "code" for c in cells)
        assert abs(int(row[1].replace(",", "")) - words) <= 50, (name, row[1], words)
        assert int(row[2]) == code, (name, row[2], code)
        minutes = words / 100 + 5 * code
        assert float(row[3]) == round(minutes / 30) / 2, (name, row[3], minutes)

def test_assignments_readme_lists_the_assignments_in_order():
    rows = re.findall(r"^\| (\d+) \| \[`(\w+)`\]\((\w+)/README\.md\)", read(HANDOUTS / "README.md"), re.M)
    assert [(int(n), a) for n, a, _ in rows] == list(enumerate(ASSIGNMENTS, start=1))
    assert all(a == folder for _, a, folder in rows)   # each links its own handout


def test_course_page_and_handout_titles_follow_the_order():
    toctree = re.findall(r"^tutorials/assignments/(\w+)/README$", read(DOCS / "course.md"), re.M)
    assert toctree == list(ASSIGNMENTS)
    for position, name in enumerate(ASSIGNMENTS, start=1):
        title = read(HANDOUTS / name / "README.md").splitlines()[0]
        assert title.startswith(f"# Assignment {position}: "), (name, title)


@pytest.mark.parametrize("name", list(ASSIGNMENTS))
def test_handout_write_up_gives_a_compare_command_of_real_techniques(name):
    text = section(read(HANDOUTS / name / "README.md"), "## Write-up")
    commands = [line for line in text.splitlines() if line.startswith("python -m toolkit compare")]
    assert len(commands) == 1, commands
    words = shlex.split(commands[0])
    techniques = words[words.index("--techniques") + 1].split(",")
    assert [t for t in techniques if t not in TECHNIQUES and t not in VARIANTS] == []
    # the student's file goes in place of the one it replaces, and back
    replaced = f"cl/{ASSIGNMENTS[name].replaces}"
    assert f"mine.cl {replaced}" in text and text.count(replaced) >= 3
