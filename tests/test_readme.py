"""The README's layout table keeps up with the code: a learner finds every file there."""
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def layout_rows():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    table = text[text.index("## Layout"):]
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
    assert not missing, f"README's layout table does not name: {missing}"


def test_floor_table_names_every_package_with_the_import_rule():
    """The floors table lists every package of toolkit/ and says what it may import, as
    tests/test_import_rule.py enforces it."""
    import test_import_rule as rule
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    table = text[text.index("| floor | package |"):]
    table = table[:table.index("\n\n")]
    named = {line.split("|")[2].strip().strip("`").removeprefix("toolkit/").rstrip("/").removesuffix(".py")
             for line in table.splitlines()[2:]}
    assert named == set(rule.BELOW) | {"cli"}, named ^ (set(rule.BELOW) | {"cli"})


def test_where_to_start_reading_names_files_that_exist():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    part = text[text.index("## Where to start reading"):text.index("## Quick start")]
    import re
    paths = re.findall(r"`((?:cl|toolkit|tutorials)/[\w/.]+)`", part)
    assert len(paths) > 15
    missing = [p for p in paths if not (ROOT / p).exists()]
    assert not missing, f"README's 'Where to start reading' names files that do not exist: {missing}"
