"""`python -m toolkit course grade` (toolkit/grading/batch.py): a class graded into grades.csv and
one report per student, with every check; a missing file or an untouched stub scores 0 unbuilt."""
import csv
import os
import shutil

import numpy as np
from pathlib import Path

from toolkit.cli import main
from toolkit.grading.checks import ASSIGNMENTS

ROOT = Path(__file__).resolve().parent.parent
FIXTURES = ROOT / "tests/fixtures/assignments"


def test_a_class_is_graded_into_a_csv_and_a_report_per_student(tmp_path, capsys):
    compaction, regen = ASSIGNMENTS["compaction"], ASSIGNMENTS["inplace_regen"]
    subs = tmp_path / "submissions"
    for folder in ("alice/cl", "bob/cl", "carol; rm -rf ~"):
        (subs / folder).mkdir(parents=True)
    shutil.copyfile(ROOT / "cl/compact.h", subs / "alice/cl/compact.h")               # the student edition's place
    shutil.copyfile(ROOT / "cl/pt_inplace_regen.cl", subs / "alice/pt_inplace_regen.cl")   # or the top
    shutil.copyfile(FIXTURES / "compaction/off_by_one_scan.cl", subs / "bob/compact.h")
    shutil.copyfile(regen.folder / regen.stub, subs / "bob/cl/pt_inplace_regen.cl")
    os.symlink(subs / "alice", subs / "mallory")   # a link to another student's work is no student

    out = tmp_path / "grades"
    assert main(["course", "grade", str(subs), "--out", str(out), "--assignments", "compaction,inplace_regen",
                 "--inputs", "12345"]) == 0
    rows = {r["student"]: r for r in csv.DictReader((out / "grades.csv").open())}
    assert set(rows) == {"alice", "bob", "carol__rm_-rf__"}
    assert rows["alice"] == {"student": "alice", "compaction": "100", "inplace_regen": "100", "total": "200",
                             "grader_error": "0", "inputs": "12345"}
    # off_by_one_scan loses the checks of the scan it breaks, and keeps the others (test_assignments.py)
    assert 0 < int(rows["bob"]["compaction"]) < 100 and rows["bob"]["inplace_regen"] == "0"
    assert rows["carol__rm_-rf__"]["total"] == "0"

    bob = (out / "reports/bob.txt").read_text()
    assert "graded on hidden inputs 12345" in bob
    assert f"inplace_regen: 0/100: {regen.replaces} is still the untouched stub" in bob
    assert "-> " in bob and "hint: " in bob          # each lost point has its reason and hint
    carol = (out / "reports/carol__rm_-rf__.txt").read_text()
    assert f"no {compaction.replaces}" in carol
    assert sorted(p.name for p in (out / "reports").iterdir()) == ["alice.txt", "bob.txt", "carol__rm_-rf__.txt"]


def test_bad_input_is_refused_with_the_reason(tmp_path, capsys):
    assert main(["course", "grade", str(tmp_path / "none"), "--out", str(tmp_path / "o")]) == 2
    assert "no such folder of submissions" in capsys.readouterr().err
    assert main(["course", "grade", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    assert "holds no student folder" in capsys.readouterr().err
    (tmp_path / "s").mkdir()
    assert main(["course", "grade", str(tmp_path), "--out", str(tmp_path / "o"), "--assignments", "scan"]) == 2
    err = capsys.readouterr().err
    assert "no assignment scan" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_hidden_inputs_are_other_inputs_than_the_public_ones():
    """Context.rng: 0 gives each check's public inputs (the student's copy), another number other
    ones, the same for the same number (a class graded again gets the same grades)."""
    from toolkit.grading.context import Context
    public, hidden, again = (Context.__new__(Context) for _ in range(3))
    public.inputs, hidden.inputs, again.inputs = 0, 12345, 12345
    assert np.array_equal(public.rng(1).random(8), np.random.default_rng(1).random(8))
    assert not np.array_equal(hidden.rng(1).random(8), public.rng(1).random(8))
    assert np.array_equal(hidden.rng(1).random(8), again.rng(1).random(8))
    assert not np.array_equal(hidden.rng(1).random(8), hidden.rng(2).random(8))   # each check its own
    assert public.seed(3) == 3 and hidden.seed(3) != 3 and hidden.seed(3) == again.seed(3)
