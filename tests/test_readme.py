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
    rows = layout_rows()
    files = [p for folder in ("toolkit", "toolkit/techniques", "cl") for p in (ROOT / folder).iterdir()
             if p.suffix in (".py", ".cl", ".h")]
    assert len(files) > 50
    missing = [p.relative_to(ROOT).as_posix() for p in files
               if not any(row_folder(row) == p.parent.relative_to(ROOT).as_posix() and f"`{p.name}`" in row
                          or f"`{p.relative_to(ROOT).as_posix()}`" in row for row in rows)]
    assert not missing, f"README's layout table does not name: {missing}"
