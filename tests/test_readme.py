"""The README stays a short front page, and the layout page (docs/layout.md) keeps up with the
code: a learner finds every file there."""
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LAYOUT = ROOT / "docs" / "layout.md"
QUICK_START = ["pip install . && python -m toolkit render", 'pip install ".[test]" && python -m pytest']
DOCS_BUILD = ['pip install ".[docs]"', "python -m sphinx -W -b html docs docs/_build/html"]


def readme():
    return (ROOT / "README.md").read_text(encoding="utf-8")


def code_block_after(text, heading):
    """The command lines of the first ```bash block after `heading` (comments after # dropped)."""
    part = text[text.index(heading):]
    block = part[part.index("```bash\n") + 8:]
    return [line.split("  #")[0].strip() for line in block[:block.index("```")].splitlines()]


def test_readme_is_a_short_front_page():
    lines = readme().splitlines()
    assert len(lines) < 120, f"README.md has {len(lines)} lines; the details belong on the site (docs/)"


def test_quick_start_is_the_two_commands():
    assert code_block_after(readme(), "## Quick start") == QUICK_START


def test_readme_names_the_docs_build_and_ci_runs_the_quick_start():
    assert code_block_after(readme(), "## Documentation") == DOCS_BUILD
    assert QUICK_START[1] in (ROOT / ".ci" / "run").read_text(encoding="utf-8")


def test_readme_links_resolve():
    targets = re.findall(r"\]\(([^)#]+)", readme())
    assert len(targets) >= 6, targets   # the picture, tutorial 2, the reading order and the internals pages
    missing = [t for t in targets if not t.startswith("http") and not (ROOT / t).exists()]
    assert not missing, f"README.md links to files that do not exist: {missing}"


def layout_rows():
    text = LAYOUT.read_text(encoding="utf-8") + "\n\n"
    table = text[text.index("Each file, floor by floor"):]
    table = table[:table.index("\n\n", table.index("| path |"))]
    return [line for line in table.splitlines() if line.startswith("| `")]


def row_folder(row):
    """The folder a row speaks of: its first path's folder (`cl/bvh.h`, ...) or the folder itself (`tests/`)."""
    first = row.split("|")[1].split("`")[1]
    return first.rstrip("/") if first.endswith("/") else first.rsplit("/", 1)[0]


def test_layout_table_names_every_file_under_toolkit_and_cl():
    """Every Python file of every package under toolkit/, and every cl/ source, is named in the
    layout table: by its own path, or by its name in a row whose first path is its folder."""
    rows = layout_rows()
    files = [p for p in sorted((ROOT / "toolkit").rglob("*.py")) + sorted((ROOT / "cl").iterdir())
             if p.suffix in (".py", ".cl", ".h") and "__pycache__" not in p.parts
             and not (p.name == "__init__.py" and p.parent != ROOT / "toolkit" and p.parent != ROOT / "cl"
                      and p.parent.parent == ROOT / "toolkit")]
    assert len(files) > 90
    missing = [p.relative_to(ROOT).as_posix() for p in files
               if not any(row_folder(row) == p.parent.relative_to(ROOT).as_posix() and f"`{p.name}`" in row
                          or f"`{p.relative_to(ROOT).as_posix()}`" in row for row in rows)]
    assert not missing, f"the layout table (docs/layout.md) does not name: {missing}"


def test_floor_table_names_every_package_with_the_import_rule():
    """The floors table lists every package of toolkit/ and says what it may import, as
    tests/test_import_rule.py enforces it."""
    import test_import_rule as rule
    text = LAYOUT.read_text(encoding="utf-8")
    table = text[text.index("| floor | package |"):]
    table = table[:table.index("\n\n")]
    named = {line.split("|")[2].strip().strip("`").removeprefix("toolkit/").rstrip("/").removesuffix(".py")
             for line in table.splitlines()[2:]}
    assert named == set(rule.BELOW) | {"cli"}, named ^ (set(rule.BELOW) | {"cli"})


def test_reading_order_names_files_that_exist():
    """The README points at the site's reading order (docs/reading_order.md), which names the files."""
    assert "(docs/reading_order.md)" in readme()[readme().index("## Where to start reading"):]
    part = (ROOT / "docs" / "reading_order.md").read_text(encoding="utf-8")
    paths = re.findall(r"`((?:cl|toolkit|tutorials)/[\w/.]+)`", part)
    assert len(paths) > 15
    missing = [p for p in paths if not (ROOT / p).exists()]
    assert not missing, f"the reading order names files that do not exist: {missing}"


def test_reading_order_links_every_tutorial_in_order():
    """Each notebook in tutorials/ has its step in the reading order, in its number's order, so a
    new tutorial (05 once was left out) cannot go missing from it."""
    part = (ROOT / "docs" / "reading_order.md").read_text(encoding="utf-8")
    notebooks = sorted(p.name for p in (ROOT / "tutorials").glob("*.ipynb"))
    linked = re.findall(r"\]\(tutorials/([\w.]+\.ipynb)\)", part)
    assert linked == notebooks, f"the reading order links {linked}; tutorials/ holds {notebooks}"
