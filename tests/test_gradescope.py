"""Gradescope autograders (issue 50): `course export --gradescope` writes one zip per assignment,
and its run_autograder, run in a temporary root laid out as Gradescope's /autograder (the
AUTOGRADER_ROOT variable stands for it), grades a submission as `course grade` does on the same
hidden inputs, into a results.json that is valid against Gradescope's format
(tests/fixtures/gradescope/results.schema.json), whatever the student submitted.

Each run_autograder is a real one: a subprocess that starts the grader, which starts its worker.
So the fixtures compared with `course grade` are one per assignment here (each graded twice);
GRADESCOPE_ALL_FIXTURES=1 compares every one of tests/fixtures/assignments. setup.sh in a fresh
Debian root is tests/gradescope_debootstrap.sh, outside the suite (root, network, minutes)."""
import json
import os
import shutil
import stat
import subprocess
import sys
import zipfile
from pathlib import Path

import jsonschema
import pytest

from test_assignments import ENDLESS_LIMIT, FIXTURES
from test_grader_security import MACRO_BOMB, STUB as REGEN_STUB, forged_reports, printf, with_lines
from toolkit.cli import main
from toolkit.grading import gradescope_run
from toolkit.grading.batch import grade_class
from toolkit.grading.checks import ASSIGNMENTS
from toolkit.grading.grade import _result, assignments_dir, grade
from toolkit.grading.gradescope_export import TIME_LIMIT, export_gradescope
from toolkit.grading.gradescope_results import results_json
from toolkit.opencl.program import MAX_SOURCE_SIZE

ROOT = Path(__file__).resolve().parent.parent
SCHEMA = json.loads((ROOT / "tests/fixtures/gradescope/results.schema.json").read_text())
INPUTS = 1357924680   # the hidden inputs' number: its digits must appear in nothing a student sees
# One fixture per assignment, each keeping some checks and losing others on hidden inputs.
SOME_FIXTURES = [("inplace_regen", "budget_off_by_one"), ("compaction", "off_by_one_scan"),
                 ("parallel_connect", "count_off_by_one"), ("mis", "no_delta_skip"),
                 ("postponed_regen", "budget_ignored"), ("mlt_mutation", "asymmetric_step")]
ALL_FIXTURES = sorted((p.parent.name, p.stem) for p in FIXTURES.glob("*/*.cl") if p.stem != "endless_loop")


@pytest.fixture(scope="module")
def zips(tmp_path_factory):
    """Every assignment's autograder, exported once (the wheel is built once)."""
    made, inputs = export_gradescope(tmp_path_factory.mktemp("export") / "zips", inputs=INPUTS,
                                     hidden_visibility="after_due_date", progress=lambda line: None)
    assert inputs == INPUTS
    return {z.stem: z for z in made}


def gradescope_root(tmp_path, zip_path, files=None):
    """Gradescope's layout under `tmp_path`: source/ (the zip unpacked), run_autograder beside it,
    submission/ holding `files` ({relative path: text or bytes}), results/."""
    root = tmp_path / "autograder"
    for folder in ("source", "submission", "results"):
        (root / folder).mkdir(parents=True)
    with zipfile.ZipFile(zip_path) as z:
        z.extractall(root / "source")
        for info in z.infolist():   # zipfile drops the mode bits; Gradescope keeps them
            mode = info.external_attr >> 16
            if mode:
                (root / "source" / info.filename).chmod(stat.S_IMODE(mode))
    shutil.copy(root / "source" / "run_autograder", root / "run_autograder")
    # The checks run as the user setup.sh makes (simd-grader) where the grader is root; here there
    # is no such user, and this venv's Python is not another user's to run (test_the_worker_runs_as_...).
    settings = json.loads((root / "source/autograder.json").read_text())
    (root / "source/autograder.json").write_text(json.dumps(dict(settings, worker_user=None)))
    for name, content in (files or {}).items():
        path = root / "submission" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(content.encode() if isinstance(content, str) else content)
    return root


def run_autograder(root, script=True):
    """Run `root`/run_autograder as Gradescope does (from `root`), with this checkout's toolkit; or,
    not `script`, what it runs (gradescope_run.run) in this process, which saves a Python start and
    the toolkit's import where a submission is refused before it is graded. Returns results.json,
    checked: valid, and nothing in it shows the hidden inputs' number."""
    if script:
        env = dict(os.environ, AUTOGRADER_ROOT=str(root), PYTHONPATH=str(ROOT),
                   PATH=os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "")]))
        run = subprocess.run([str(root / "run_autograder")], cwd=root, env=env, capture_output=True, text=True,
                             timeout=600)
        assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    else:
        assert gradescope_run.run(root) == 0
    text = (root / "results" / "results.json").read_text()
    results = json.loads(text)
    jsonschema.validate(results, SCHEMA)
    assert str(INPUTS) not in text
    assert sorted(p.name for p in (root / "results").iterdir()) == ["results.json"]
    return results


def autograde(tmp_path, zip_path, files, script=True):
    return run_autograder(gradescope_root(tmp_path, zip_path, files), script)


def by_name(results):
    return {t["name"].split(":")[0]: t for t in results["tests"]}


def solution(name):
    return (ROOT / "cl" / ASSIGNMENTS[name].replaces).read_text()


def stub(name):
    a = ASSIGNMENTS[name]
    return (assignments_dir() / name / a.stub).read_text()


# --- the zip -----------------------------------------------------------------------------------

def test_each_zip_holds_the_scripts_the_wheel_and_the_settings(zips):
    assert set(zips) == set(ASSIGNMENTS)
    for name, path in zips.items():
        with zipfile.ZipFile(path) as z:
            names = z.namelist()
            wheel = next(n for n in names if n.endswith(".whl"))
            assert sorted(names) == sorted(["setup.sh", "run_autograder", "autograder.json", wheel])
            for script in ("setup.sh", "run_autograder"):
                assert stat.S_IMODE(z.getinfo(script).external_attr >> 16) == 0o755
                checked = subprocess.run(["bash", "-n"], input=z.read(script), capture_output=True)
                assert checked.returncode == 0, checked.stderr
            settings = json.loads(z.read("autograder.json"))
            assert settings == {"assignment": name, "inputs": INPUTS, "hidden_visibility": "after_due_date",
                                "time_limit": 30, "worker_user": "simd-grader", "wheel": wheel}
            assert b"useradd --system --create-home --shell /usr/sbin/nologin simd-grader" in z.read("setup.sh")
            assert wheel.encode() in z.read("setup.sh")
            with zipfile.ZipFile(z.open(wheel)) as w:   # the toolkit with its reference solutions
                replaces = ASSIGNMENTS[name].replaces
                assert w.read(f"toolkit/cl/{replaces}") == (ROOT / "cl" / replaces).read_bytes()
                assert "toolkit/grading/gradescope_run.py" in w.namelist()
                metadata = w.read(next(n for n in w.namelist() if n.endswith(".dist-info/METADATA"))).decode()
                assert "Requires-Dist: pyopencl" in metadata   # the dependencies come from the package index


def test_export_refuses_bad_input_with_the_reason(tmp_path, capsys):
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("mine")
    for args, message in ((["--gradescope", str(tmp_path / "full")], "not an empty folder"),
                          (["--gradescope", "--assignments", "scan", str(tmp_path / "a")], "no assignment scan"),
                          (["--gradescope", "--inputs", "0", str(tmp_path / "b")], "--inputs must be a number"),
                          (["--inputs", "5", str(tmp_path / "c")], "give them with --gradescope"),
                          (["--time-limit", "5", str(tmp_path / "e")], "give them with --gradescope"),
                          (["--gradescope", "--hidden-visibility", "later", str(tmp_path / "d")], "invalid choice")):
        with pytest.raises(SystemExit) if "invalid" in message else _no_exit() as exited:
            code = main(["course", "export", *args])
        err = capsys.readouterr().err
        assert (exited.value.code if exited else code) == 2 and message in err and "Traceback" not in err, err
    assert [p.name for p in tmp_path.iterdir()] == ["full"]


class _no_exit:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False


# --- what a student gets -----------------------------------------------------------------------

@pytest.mark.parametrize("name", list(ASSIGNMENTS))
def test_the_reference_solution_scores_100_and_the_stub_0(name, zips, tmp_path):
    results = autograde(tmp_path / "solution", zips[name], {f"cl/{ASSIGNMENTS[name].replaces}": solution(name)})
    assert results["score"] == 100, results
    assert [t["name"].split(":")[0] for t in results["tests"]] == [c.name for c in ASSIGNMENTS[name].checks]
    for check, test in zip(ASSIGNMENTS[name].checks, results["tests"]):
        assert (test["score"], test["max_score"], test["status"]) == (check.points, check.points, "passed"), test
        # the public checks (the student's copy runs them) at once, the others as the export chose
        assert test["visibility"] == ("after_due_date" if check.hidden else "visible")
    assert "other inputs than the ones in your copy" in results["output"]

    results = autograde(tmp_path / "stub", zips[name], {ASSIGNMENTS[name].replaces: stub(name)}, script=False)
    assert results["score"] == 0 and "still the untouched stub" in results["output"]
    assert [t["visibility"] for t in results["tests"]] == ["visible"]


def test_setup_checks_that_the_reference_solution_scores_100(zips, tmp_path, capsys):
    """setup.sh ends with this: Gradescope's image fails to build unless the reference scores 100."""
    root = gradescope_root(tmp_path, zips["inplace_regen"])
    assert gradescope_run.check_solution(root / "source") == 0
    assert capsys.readouterr().out.endswith("the reference solution scores 100\n")
    assert "--check-solution" in (root / "source" / "setup.sh").read_text()


def fixture_pairs():
    return ALL_FIXTURES if os.environ.get("GRADESCOPE_ALL_FIXTURES") == "1" else SOME_FIXTURES


@pytest.mark.parametrize("name,fixture", fixture_pairs())
def test_a_fixture_scores_what_course_grade_gives_it_on_the_same_inputs(name, fixture, zips, tmp_path):
    a = ASSIGNMENTS[name]
    text = (FIXTURES / name / f"{fixture}.cl").read_text()
    results = autograde(tmp_path / "gradescope", zips[name], {a.replaces: text})
    student = tmp_path / "class" / "student"
    student.mkdir(parents=True)
    (student / a.replaces).write_text(text)
    grades, _ = grade_class(tmp_path / "class", tmp_path / "grades", [name], time_limit=TIME_LIMIT, inputs=INPUTS,
                            progress=lambda line: None)
    offline = grades["student"][name]
    assert results["score"] == offline["score"], (results, offline)
    assert {n: t["score"] for n, t in by_name(results).items()} == {c["name"]: c["earned"] for c in offline["checks"]}


# --- errors a student can act on ---------------------------------------------------------------

def test_no_file_or_the_wrong_one_is_a_score_of_0_saying_what_to_do(zips, tmp_path):
    name = "compaction"
    zip_path = zips[name]
    cases = {
        "empty": ({}, ["holds no file", "grades compact.h"]),
        "renamed": ({"mine.cl": solution(name), "notes.txt": "x"},
                    ["has no compact.h", "mine.cl, notes.txt", "Name your file compact.h"]),
        "another assignment's": ({"bdpt_regeneration.h": solution("postponed_regen")},
                                 ["bdpt_regeneration.h is the file of assignment postponed_regen"]),
        "in a folder": ({"my_course/cl/compact.h": solution(name)}, ["is at my_course/cl/compact.h",
                                                                    "not a folder that holds it"]),
    }
    for case, (files, words) in cases.items():
        results = autograde(tmp_path / case.replace(" ", "_").replace("'", ""), zip_path, files, script=False)
        assert results["score"] == 0 and len(results["tests"]) == 1, (case, results)
        for word in words:
            assert word in results["output"] and word in results["tests"][0]["output"], (case, word, results)


def test_a_kernel_that_does_not_build_or_finish_loses_its_points_with_the_reason(zips, tmp_path):
    root = gradescope_root(tmp_path / "broken", zips["compaction"],
                           {"compact.h": (FIXTURES / "compaction/does_not_compile.cl").read_text()})
    results = run_autograder(root)
    assert results["score"] == 0 and "does not build" in results["output"]
    for test in results["tests"]:
        assert test["output"].startswith("the kernel does not build: ") and "compact.h:48:" in test["output"], test
        assert "hint: fix the compiler's first error" in test["output"]
    # a kernel that does not finish: its check is stopped at the limit (the export's --time-limit,
    # here lowered in the unpacked zip to test_assignments' limit for it), a fresh worker grades the rest
    root = gradescope_root(tmp_path / "endless", zips["parallel_connect"],
                           {"bdpt_parallel_connect.cl": (FIXTURES / "parallel_connect/endless_loop.cl").read_text()})
    settings = json.loads((root / "source/autograder.json").read_text())
    (root / "source/autograder.json").write_text(json.dumps(dict(settings, time_limit=ENDLESS_LIMIT)))
    results = run_autograder(root)
    count = by_name(results)["count"]
    assert count["score"] == 0
    assert count["output"].startswith(f"stopped after {ENDLESS_LIMIT} s: the kernel does not finish"), count
    assert results["score"] == 100 - count["max_score"]


def test_a_broken_autograder_still_writes_a_result_the_student_can_read(zips, tmp_path):
    root = gradescope_root(tmp_path, zips["inplace_regen"], {"pt_inplace_regen.cl": solution("inplace_regen")})
    (root / "source/autograder.json").write_text("{")
    results = run_autograder(root)
    assert results["score"] == 0 and "tell your instructor" in results["output"]


# --- the sandbox: the suite's attacks through run_autograder ------------------------------------

NAME = "inplace_regen"
FILE = ASSIGNMENTS[NAME].replaces


def attacks(root):
    """The grader attacks of tests/test_grader_security.py a submission can make, aimed at this
    container: {attack: (files, what its results must say)}. The macro bomb is graded under a
    smaller memory limit in that file; here it meets the default 4 GiB (see test_the_macro_bomb)."""
    settings = root / "source" / "autograder.json"
    whole_results = json.dumps({"score": 100, "tests": [{"name": "all", "score": 100, "max_score": 100}]})
    return {
        # 1. printf lines shaped like the worker's reports, and like a whole results.json
        "forged reports": ({FILE: with_lines(REGEN_STUB, *forged_reports(), "    " + printf(whole_results))}, None),
        # 2. including what the assignment does not allow: the settings (the inputs' number) by
        # absolute and relative path, the reference solution, a file by another directive
        "include the settings": ({FILE: f'#include "{settings}"\n' + solution(NAME)}, "an absolute path"),
        "include by a folder": ({FILE: '#include "../source/autograder.json"\n' + solution(NAME)}, "names a folder"),
        "include the solution": ({FILE: f'#include "{FILE}"\n' + REGEN_STUB}, "the toolkit's solution"),
        "include by %:": ({FILE: '%:include "/proc/self/environ"\n' + solution(NAME)}, "on a line of its own"),
        # 3. a symbolic link to the settings, in place of the file
        "link to the settings": ({}, "a symbolic link to a file in another folder"),
        # 4. an include bomb: 900 spellings of its own name
        "include bomb": ({FILE: "\n".join(f'#include "{"./" * i}{FILE}"' for i in range(1, 900)) + "\n"
                          + solution(NAME)}, "names a folder"),
        # 5. a file over the size a build may have
        "too large": ({FILE: solution(NAME) + "//" + "x" * MAX_SOURCE_SIZE}, "more than the 4,000,000"),
        # 6. a results.json of its own, planted in the submission (and a kernel that would write one)
        "planted results": ({FILE: with_lines(REGEN_STUB, "    " + printf(whole_results)),
                             "results/results.json": whole_results, "results.json": whole_results}, None),
    }


def test_the_attacks_fail_and_change_nothing_but_their_own_checks(zips, tmp_path):
    """Each attack scores what the stub scores on the same inputs (0), or is refused with every
    check losing its points for the reason; results.json always lists exactly the assignment's
    checks, each worth its points, and none passes. (7., a kernel that does not finish, is
    test_a_kernel_that_does_not_build_or_finish_...; the compiler's memory limit is test_the_macro_bomb.)"""
    checks = [c.name for c in ASSIGNMENTS[NAME].checks]
    stub_file = tmp_path / "stub" / FILE
    stub_file.parent.mkdir()
    stub_file.write_text(REGEN_STUB)
    the_stub = {c["name"]: c["earned"] for c in grade(NAME, stub_file, inputs=INPUTS)["checks"]}
    assert set(the_stub.values()) == {0}
    probe = gradescope_root(tmp_path / "probe", zips[NAME])
    for i, (attack, (files, refused)) in enumerate(attacks(probe).items()):
        root = gradescope_root(tmp_path / f"attack{i}", zips[NAME], files)
        if attack == "link to the settings":
            (root / "submission" / FILE).symlink_to(root / "source" / "autograder.json")
        results = run_autograder(root, script=not refused)   # a refusal: the same grading, in this process
        tests = by_name(results)
        assert list(tests) == checks, (attack, results)
        assert results["score"] == 0 and all(t["score"] == 0 and t["status"] == "failed" for t in tests.values()), \
            (attack, results)
        assert {n: t["max_score"] for n, t in tests.items()} == {c.name: c.points for c in ASSIGNMENTS[NAME].checks}
        if refused:
            assert all(t["output"].startswith("the kernel does not build") and refused in t["output"]
                       for t in tests.values()), (attack, results)
        else:
            assert {n: t["score"] for n, t in tests.items()} == the_stub, attack
            assert not any("grader failed" in t["output"] for t in tests.values()), (attack, results)


@pytest.mark.skipif(os.environ.get("GRADESCOPE_MACRO_BOMB") != "1",
                    reason="half a minute of a core and up to 4 GiB: GRADESCOPE_MACRO_BOMB=1 runs it")
def test_the_macro_bomb(zips, tmp_path):
    results = autograde(tmp_path, zips[NAME], {FILE: with_lines(REGEN_STUB, *MACRO_BOMB,
                                                                "    int bomb = BOMB(1 +) 0; (void)bomb;")})
    assert results["score"] == 0
    assert all(t["output"].startswith("the kernel does not build: the compiler crashed") for t in results["tests"])


@pytest.mark.skipif(os.geteuid() != 0, reason="only root can run the worker as another user")
def test_the_worker_runs_as_the_unprivileged_user_and_cannot_write_the_graders_files(tmp_path):
    """Where the grader is root (Gradescope's container), the worker's limits switch it to
    Limits.user before it starts (limit_worker): its user id and groups are that user's, and a
    folder of the grader's (results/) is not its to write. (A Python worker cannot be run so here:
    this venv's interpreter lies in root's home. tests/gradescope_debootstrap.sh grades as the
    user setup.sh makes.)"""
    import pwd
    from toolkit.grading.limits import Limits, limit_worker, worker_account, worker_environment
    limits = Limits(user="nobody")
    account = worker_account(limits)
    results = tmp_path / "results"
    results.mkdir()
    run = subprocess.run(["sh", "-c", f"id -u; id -G; touch {results}/results.json"], capture_output=True, text=True,
                         env=worker_environment(tmp_path, ROOT, account), cwd="/",
                         preexec_fn=limit_worker(limits, 100, account))
    uid, groups = run.stdout.split()[:2]
    assert (int(uid), groups) == (pwd.getpwnam("nobody").pw_uid, str(account.pw_gid))
    assert run.returncode != 0 and "Permission denied" in run.stderr and not list(results.iterdir())
    env = worker_environment(tmp_path, ROOT, account)
    assert env["HOME"] == account.pw_dir and env["USER"] == "nobody"
    with pytest.raises(ValueError, match="does not exist"):
        worker_account(Limits(user="no-such-user-here"))


# --- results.json from a result ----------------------------------------------------------------

def test_results_follow_the_visibility_chosen_and_count_a_skipped_check_neither_way():
    a = ASSIGNMENTS["compaction"]
    reasons = {c.name: None for c in a.checks}
    reasons.update(scan="the total of group 3 is 17, numpy gives 18",
                   races="skipped: this check needs Oclgrind (an OpenCL simulator), which is not installed here")
    result = _result(a, "compact.h", dict(reasons), {}, None, 2.0)
    for visibility in ("visible", "after_due_date", "after_published", "hidden"):
        results = results_json(result, visibility)
        jsonschema.validate(results, SCHEMA)
        tests = by_name(results)
        assert {n for n, t in tests.items() if t["visibility"] == visibility} >= {c.name for c in a.checks if c.hidden}
        assert all(tests[c.name]["visibility"] == "visible" for c in a.checks if not c.hidden)
    assert results["score"] == result["score"] == round(75 * 100 / 90)
    assert (tests["scan"]["score"], tests["scan"]["status"]) == (0, "failed")
    assert tests["scan"]["output"].startswith("the total of group 3 is 17") and "\nhint: " in tests["scan"]["output"]
    assert (tests["races"]["score"], tests["races"]["max_score"]) == (0, 0)
    assert "not counted" in tests["races"]["output"]
    assert "rescaled" in results["output"]


def test_the_schema_refuses_what_gradescope_would_not_read():
    for wrong in ({"tests": [{"name": "x"}]},                                 # no score anywhere
                  {"score": 1, "visibility": "later"},
                  {"score": 1, "tests": [{"score": 1, "status": "ok"}]},
                  {"score": 1, "tests": [{"score": 1, "max_points": 2}]},      # a misspelt field
                  {"score": "100"}):
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate(wrong, SCHEMA)
    jsonschema.validate({"tests": [{"score": 1, "max_score": 2, "visibility": "after_published"}]}, SCHEMA)
