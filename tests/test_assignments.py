"""The course assignments' autograder (toolkit/grade.py, tutorials/assignments/): the reference
solutions score 100, the untouched stubs 0, each deliberately wrong kernel (tests/fixtures/
assignments/) loses exactly the checks it breaks, a kernel that does not build or does not
finish costs its points while the grader goes on, and the handouts name only files and
commands that exist. Grading is subprocess-heavy: builds come from the on-disk caches."""
import json
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from toolkit.grade import ASSIGNMENTS, assignments_dir, grade

ROOT = Path(__file__).resolve().parent.parent
FIXTURES = ROOT / "tests" / "fixtures" / "assignments"
LIMIT = 60   # seconds to grade one submission on a 2-core machine (issue 12)

# fixture -> the checks it must lose (it keeps every other one)
WRONG = {
    ("compaction", "off_by_one_scan"): {"scan", "compact", "edges", "one_atomic", "twice", "render"},
    ("compaction", "missing_barrier"): {"scan", "compact", "edges", "one_atomic", "twice", "render"},
    ("compaction", "atomic_per_item"): {"one_atomic"},
    ("parallel_connect", "wrong_base"): {"search", "search_edges", "image"},
    ("parallel_connect", "count_off_by_one"): {"count"},
    ("mis", "power_not_squared"): {"power"},
    ("mis", "no_delta_skip"): {"balance_sum", "balance", "power"},
    ("inplace_regen", "budget_off_by_one"): {"ids", "any_alive", "regenerated"},
    ("inplace_regen", "any_alive_only_started"): {"any_alive", "image"},
}


def lost(result):
    return {c["name"] for c in result["checks"] if c["earned"] == 0}


def assert_points_add_up(result):
    assert result["max"] == 100
    for c in result["checks"]:
        assert c["earned"] in (0, c["points"])
        assert (c["reason"] is None) == (c["earned"] == c["points"]), c
        assert c["reason"] is None or "\n" not in c["reason"]    # one line a student can act on
    assert result["seconds"] < LIMIT, result


@pytest.mark.parametrize("name", list(ASSIGNMENTS))
def test_reference_solution_scores_100(name):
    result = grade(name, solution=True)
    assert result["score"] == 100, [c for c in result["checks"] if c["reason"]]
    assert_points_add_up(result)


@pytest.mark.parametrize("name", list(ASSIGNMENTS))
def test_untouched_stub_builds_and_scores_0_on_every_check(name):
    a = ASSIGNMENTS[name]
    result = grade(name, assignments_dir() / name / a.stub)
    assert result["score"] == 0
    for c in result["checks"]:
        assert "does not build" not in c["reason"] and "crashed" not in c["reason"], c
    assert_points_add_up(result)


@pytest.mark.parametrize("name,fixture", sorted(WRONG))
def test_wrong_kernel_loses_the_checks_it_breaks_and_keeps_the_rest(name, fixture):
    result = grade(name, FIXTURES / name / f"{fixture}.cl")
    print(fixture, result["score"], [(c["name"], c["reason"]) for c in result["checks"] if c["reason"]])
    assert lost(result) == WRONG[(name, fixture)]
    assert_points_add_up(result)


def test_every_fixture_is_graded_by_a_test():
    files = {(p.parent.name, p.stem) for p in FIXTURES.glob("*/*.cl")}
    assert files == set(WRONG) | {("compaction", "does_not_compile"), ("parallel_connect", "endless_loop")}
    for name in ASSIGNMENTS:
        assert sum(1 for a, _ in WRONG if a == name) >= 2


def test_kernel_that_does_not_build_scores_0_with_the_compiler_message_at_its_line():
    result = grade("compaction", FIXTURES / "compaction" / "does_not_compile.cl")
    assert result["score"] == 0
    for c in result["checks"]:
        assert c["reason"].startswith("the kernel does not build:"), c
        assert "does_not_compile.cl:48:" in c["reason"] and "zero" in c["reason"], c
    assert result["seconds"] < 10


def test_endless_loop_is_stopped_and_the_grader_goes_on():
    limit = 10
    result = grade("parallel_connect", FIXTURES / "parallel_connect" / "endless_loop.cl", time_limit=limit)
    reasons = {c["name"]: c["reason"] for c in result["checks"]}
    print(reasons)
    assert lost(result) == {"count", "image"}
    assert reasons["count"].startswith(f"stopped after {limit} s")
    assert result["score"] == 45
    assert result["seconds"] < 2 * limit + 30


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "toolkit", "grade", *args], cwd=ROOT, capture_output=True, text=True)


def test_cli_grades_a_folder_as_json_rows_and_refuses_bad_input(tmp_path):
    for name in ("a.cl", "b.cl"):
        (tmp_path / name).write_text((FIXTURES / "compaction" / "does_not_compile.cl").read_text())
    run = run_cli("compaction", "--kernel", *sorted(str(p) for p in tmp_path.glob("*.cl")), "--json")
    assert run.returncode == 0, run.stderr
    rows = [json.loads(line) for line in run.stdout.splitlines()]
    assert [Path(r["file"]).name for r in rows] == ["a.cl", "b.cl"] and all(r["score"] == 0 for r in rows)
    for args, message in ((["compaction"], "--kernel"), (["compaction", "--kernel", str(tmp_path / "none.cl")], "no such"),
                          (["nonsense", "--solution"], "invalid choice")):
        run = run_cli(*args)
        assert run.returncode == 2 and "Traceback" not in run.stderr and message in run.stderr, run.stderr
    run = run_cli("mis", "--stub")
    assert run.returncode == 0 and "TODO" in run.stdout


# --- the handouts are linted -------------------------------------------------------------------

HANDOUTS = sorted(assignments_dir().glob("**/README.md"))
PLACEHOLDERS = {"mine.cl", "THIS_FILE", "DIR/*.cl", "submissions/*.cl"}


def named_files(text):
    """Paths a handout names in backticks: anything with a slash or a source-file suffix."""
    names = re.findall(r"`([^`\s]+)`", text)
    return [n for n in names if re.search(r"\w\.(cl|h|py|md|ipynb)$", n) or n.endswith("/")]


def commands(text):
    """Commands on their own lines (code blocks) and in backticks."""
    lines = [line.strip().lstrip("$ ").split("  #")[0] for line in text.splitlines()
             if line.strip().lstrip("$ ").startswith("python -m toolkit")]
    return lines + re.findall(r"`(python -m toolkit [^`]+)`", text)


@pytest.mark.parametrize("handout", HANDOUTS, ids=lambda p: p.parent.name)
def test_handout_names_only_files_that_exist(handout):
    text = handout.read_text(encoding="utf-8")
    missing = [n for n in named_files(text) if n not in PLACEHOLDERS
               and not any((base / n).exists() for base in (ROOT, handout.parent, ROOT / "cl", assignments_dir()))]
    assert not missing, f"{handout} names files that do not exist: {missing}"


@pytest.mark.parametrize("handout", HANDOUTS, ids=lambda p: p.parent.name)
def test_handout_commands_parse_and_the_cheap_ones_run(handout, tmp_path):
    """Every command parses with the real CLI parser; the --stub ones run. The --solution and the
    grading of a stub run in the tests above; a student's `mine.cl` is the stub there."""
    from toolkit.cli import build_parser
    found = commands(handout.read_text(encoding="utf-8"))
    assert found, f"{handout} names no command"
    for line in found:
        words = shlex.split(line.split(">")[0])
        assert words[:3] == ["python", "-m", "toolkit"], line
        build_parser().parse_args(words[3:])            # exits (fails the test) on a bad command
        if "--stub" in words:
            run = subprocess.run([sys.executable, "-m", "toolkit", *words[3:]], capture_output=True, text=True)
            assert run.returncode == 0 and "TODO" in run.stdout, line
