"""The grader cannot be fooled by what it grades (issue 24): a kernel's printf cannot write the
grader's reports, a line on the report pipe that is not the report expected is the grader's own
error (and the rest of a batch is graded), a submission includes only what its assignment allows,
the compiler and the worker run under limits, and the worker dies with the grader.

Full grades are few (each costs a worker and builds): inplace_regen's, the cheapest assignment.
What can be tested as a function (the include rules, the report protocol) is tested so, and
fuzzed with hypothesis."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from test_assignments import FIXTURES, graded
from toolkit.cli import main
from toolkit.grading import runner
from toolkit.grading.channel import Expected, ProtocolError, parse_report, report_line
from toolkit.grading.grade import ASSIGNMENTS, Limits, assignments_dir, grade
from toolkit.grading.limits import GradingStopped, stop_on_signals
from toolkit.grading.sources import SubmissionSources, directives
from toolkit.opencl.program import MAX_SOURCE_SIZE, KernelBuildError, cl_dir, expand_includes

ROOT = Path(__file__).resolve().parent.parent
NAME = "inplace_regen"
A = ASSIGNMENTS[NAME]
STUB = (assignments_dir() / NAME / A.stub).read_text()
FAKE_WORKER = ROOT / "tests" / "fixtures" / "grader" / "fake_worker.py"
CHECKS = [c.name for c in A.checks]


def with_lines(text, *lines, after="    int started = 0;\n"):
    """The stub with `lines` inserted after the line `after` (in the kernel's body, by default)."""
    assert after in text
    return text.replace(after, after + "".join(line + "\n" for line in lines), 1)


def printf(text):
    """A C printf statement that prints `text` and a newline."""
    return 'printf("%s\\n", "' + text.replace("\\", "\\\\").replace('"', '\\"') + '");'


def forged_reports():
    """printf lines shaped like the worker's reports, old (on stdout) and new (a guessed nonce):
    every check passed, a wrong-shaped line (it crashed a batch), a suspect one (endless fresh
    workers), a start (a reset deadline)."""
    lines = ['{"grade-worker": 1, "start": "build"}']
    for check in ["build"] + CHECKS:
        lines += [json.dumps({"grade-worker": 1, "done": check, "reason": None, "suspect": False, "fresh": True,
                              "seconds": 0.1}),
                  json.dumps({"nonce": "0" * 32, "done": check, "reason": None, "suspect": False, "seconds": 0.1})]
    lines += ['{"grade-worker": 1, "done": "ids"}',
              '{"grade-worker": 1, "done": "ids", "reason": "x", "suspect": true, "fresh": false, "seconds": 1}',
              '{"grade-worker": 1, "start": "image"}']
    return ["    if (gid == 0) {", *("        " + printf(line) for line in lines), "    }"]


def by_check(result):
    return {c["name"]: (c["earned"], c["reason"]) for c in result["checks"]}


def test_a_kernel_that_prints_reports_scores_what_the_stub_scores(tmp_path):
    """Before: 100/100 for the untouched stub with these printfs."""
    forging = tmp_path / "forging.cl"
    forging.write_text(with_lines(STUB, *forged_reports()))
    result, stub = grade(NAME, forging), graded(NAME, "stub")
    assert "error" not in result, result["error"]
    assert by_check(result) == by_check(stub) and result["score"] == stub["score"] == 0


# --- the report pipe: what the grader accepts ----------------------------------------------------

def test_the_grader_accepts_only_the_report_of_the_check_that_runs():
    nonce = "n" * 32
    ok = {"start": "build"}
    assert parse_report(report_line(nonce, **ok)[:-1], nonce) == ok
    for line in (b"{not json", b"[]", report_line("m" * 32, **ok)[:-1], report_line(nonce, start=3)[:-1],
                 report_line(nonce, done="build", reason=None, suspect=False, seconds=float("nan"))[:-1],
                 report_line(nonce, done="build", reason=None, suspect="no", seconds=1)[:-1],
                 report_line(nonce, done="build", reason=None, suspect=False, seconds=1, fresh=True)[:-1],
                 b"x" * 70000):
        with pytest.raises(ProtocolError):
            parse_report(line, nonce)
    expected = Expected(["build", "ids"])
    expected.accept({"start": "build"})
    for wrong in ({"start": "build"}, {"start": "ids"}, {"done": "ids"}):   # a second start: no new deadline
        with pytest.raises(ProtocolError):
            expected.accept(wrong)
    expected.accept({"done": "build"})
    with pytest.raises(ProtocolError):
        expected.accept({"done": "build"})


@pytest.fixture
def fake_worker(monkeypatch):
    monkeypatch.setattr(runner, "WORKER", [str(FAKE_WORKER)])


def test_a_batch_grades_every_file_when_the_grader_fails_on_some(fake_worker, tmp_path, capsys):
    """Before: a wrong-shaped line ended the batch with a traceback (KeyError: 'seconds')."""
    files = []
    for behaviour in ("malformed", "nonce", "restart"):
        files.append(tmp_path / f"{behaviour}.cl")
        files[-1].write_text(f"// fake: {behaviour}\n" + STUB)
    files.append(tmp_path / "does_not_build.cl")   # graded by the real worker: it refuses the include
    files[-1].write_text('#include "bdpt.h"\n' + STUB)
    code = main(["grade", NAME, "--kernel", *map(str, files), "--json", "--time-limit", "20"])
    out, err = capsys.readouterr()
    rows = [json.loads(line) for line in out.splitlines()]
    assert code == 1 and "the grader failed on some files" in err and "Traceback" not in err
    assert [Path(r["file"]).name for r in rows] == [f.name for f in files]
    malformed, nonce, restart, broken = rows
    assert "not JSON" in malformed["error"] and "nonce" in nonce["error"]
    assert "the start of 'ids' while 'ids' runs" in restart["error"] and restart["seconds"] < 20   # no reset deadline
    for row in (malformed, nonce, restart):
        assert row["score"] == 0 and all(c["reason"].startswith("not graded: the grader's worker sent")
                                         for c in row["checks"]), row
    assert "error" not in broken and broken["score"] == 0
    assert all(c["reason"].startswith('the kernel does not build: does_not_build.cl:1: error: #include "bdpt.h"')
               for c in broken["checks"])


def test_a_check_failing_in_the_host_code_runs_again_once_in_a_fresh_worker(fake_worker, tmp_path, monkeypatch):
    """Before: a forged suspect line started fresh workers for ever (38 in 40 s). Each worker
    runs in a folder of its own, with a clean environment, under its limits."""
    monkeypatch.setenv("GRADER_SECRET", "hunter2")
    count = tmp_path / "workers"
    kernel = tmp_path / "suspect.cl"
    kernel.write_text(f"// fake: suspect {count}\n" + STUB)
    result = grade(NAME, kernel)
    assert {c["reason"] for c in result["checks"]} == {"RuntimeError: fake"}
    workers = [json.loads(line) for line in count.read_text().splitlines()]
    # each check but the first fails after others ran in its worker, and runs once more, fresh
    assert len(workers) == len(CHECKS) <= runner.MAX_RUNS * len(CHECKS)
    for worker in workers:
        assert Path(worker["cwd"]).name == "worker" and Path(worker["cwd"]).parent.name.startswith("grade-")
        assert not Path(worker["cwd"]).exists()   # removed with the grading folder
        assert "GRADER_SECRET" not in worker["env"] and worker["env"]["TMPDIR"] == worker["cwd"]
        assert worker["limits"]["RLIMIT_DATA"] == Limits().memory and worker["limits"]["RLIMIT_CORE"] == 0


# --- what a submission may include -------------------------------------------------------------

@pytest.fixture
def folder(tmp_path):
    """A grading folder: the student's file (written by each test) and a grader's file beside it."""
    (tmp_path / "grader_helper.h").write_text("#define HELPER 1\n")
    return tmp_path


def expand(folder, text, headers=A.headers):
    (folder / A.replaces).write_text(text)
    return expand_includes(A.replaces, SubmissionSources(folder, A.replaces, headers))


def file_directives(source):
    """The directives in `source` that read a file."""
    lines = source.splitlines()
    return [lines[n - 1] for n, d in directives(source) if "include" in d or d in ("import", "embed")]


REFUSED = {
    f'#include "{cl_dir() / A.replaces}"': "an absolute path",
    '#include "/proc/self/environ"': "an absolute path",
    '#include "../cl/pt_inplace_regen.cl"': "names a folder",
    '#include "sub/x.h"': "names a folder",
    f'#include "{A.replaces}"': "the toolkit's solution, and cannot include it",
    '#include "bdpt.h"': "allowed: extend_in_place.h",
    '#include ".hidden.h"': "not a plain file name",
    '#include </proc/self/environ>': "on a line of its own",
    '#include "extend_in_place.h" // the path tracer': "with no comment after it",
    '%:include "/proc/self/environ"': "on a line of its own",
    '??=include "/proc/self/environ"': "on a line of its own",
    '#inc\\\nlude "/proc/self/environ"': "on a line of its own",
    '# /* a comment */ include "/proc/self/environ"': "on a line of its own",
    '#include F': "on a line of its own",   # F: a macro that names a file
    '#include_next "extend_in_place.h"': "#include_next",
    '#import "extend_in_place.h"': "#import",
    '#embed "/proc/self/environ"': "#embed",
    # inlined inside a comment, common.h's own "*/" would end the comment and the next line be read
    '/*\n#include "extend_in_place.h"\n#include </proc/self/environ>\n*/': "inside a comment",
    '#define X \\\n#include "extend_in_place.h"': "after a line continuation",
    '/*\n#include <pyopencl-random123/philox.cl>\n#include </proc/self/environ>\n*/': "inside a comment",
}


@pytest.mark.parametrize("line", list(REFUSED))
def test_an_include_outside_the_allowed_files_is_refused_with_its_line(folder, line):
    with pytest.raises(KernelBuildError) as refused:
        expand(folder, "int a;\n" + line + "\n")
    message = str(refused.value)
    where = 3 if line.startswith(("/*", "#define")) else 2   # the include's line
    assert message.startswith(f"{A.replaces}:{where}: error: ") and REFUSED[line] in message, message


def test_a_symbolic_link_out_of_the_folder_is_refused(folder):
    (folder / "link.h").symlink_to(cl_dir() / A.replaces)
    with pytest.raises(KernelBuildError, match="a symbolic link to a file outside your folder"):
        expand(folder, '#include "link.h"\n')


def test_allowed_includes_come_in_once_each_whatever_their_name(folder):
    source = expand(folder, '#include "extend_in_place.h"\n#include "grader_helper.h"\n#include "grader_helper.h"\n'
                    + STUB)
    assert source.count('#line 1 "grader_helper.h"') == 1 and source.count('#line 1 "extend_in_place.h"') == 1
    # the compiler reads no file itself (pyopencl's Random123 headers include C++ ones, for C++ only)
    assert file_directives(source) == file_directives(expand_includes(A.replaces))


def test_an_include_bomb_stops_at_its_first_line_and_the_source_size_is_capped(folder, tmp_path):
    """Before: 900 spellings of its own name (534 KB) expanded to 482 MB (2.2 GB, 466 s)."""
    spellings = [f'#include "{"./" * i}{A.replaces}"' for i in range(1, 900)]
    with pytest.raises(KernelBuildError, match=r":1: error: .*names a folder"):
        expand(folder, "\n".join(spellings) + "\n" + STUB)
    for name in ("big1.h", "big2.h"):   # two large files beside it, each under the limit
        (folder / name).write_text(("// " + "x" * 97 + "\n") * (MAX_SOURCE_SIZE // 200 + 1000))
    with pytest.raises(KernelBuildError, match="over 4,000,000 characters"):
        expand(folder, '#include "big1.h"\n#include "big2.h"\n')
    large = tmp_path / "large.cl"
    large.write_text(STUB + "//" + "x" * MAX_SOURCE_SIZE)
    result = grade(NAME, large)   # refused before a worker starts
    assert result["score"] == 0 and result["seconds"] < 1
    assert all("more than the 4,000,000 a build may have" in c["reason"] for c in result["checks"])


# --- the worker's limits -----------------------------------------------------------------------

# Each level doubles the one before, inside a macro's argument (pre-expanded in memory): 2^24
# copies of the innermost text, about 400 MB of tokens, more with the parser's tree.
MACRO_BOMB = ["#define D(x) x x", "#define E(x) D(D(D(D(x))))", "#define F(x) E(E(E(E(x))))",
              "#define BOMB(x) F(F(E(x)))"]


def macro_bomb(tmp_path):
    kernel = tmp_path / "bomb.cl"
    kernel.write_text(with_lines(STUB, *MACRO_BOMB, "    int bomb = BOMB(1 +) 0; (void)bomb;"))
    return kernel


def test_a_macro_bomb_is_stopped_by_the_memory_limit_as_a_compiler_crash(tmp_path):
    """Before: a few hundred bytes would reach ~10 GB within the 180 s build limit. At the limit
    an allocation fails, and the compiler dies of it in one of two ways: it says so and aborts
    (bad_alloc, "Allocation failed": the reason then says out of memory; PoCL's, and Intel's in
    4 of 4 runs at this limit here), or it uses the memory it did not get and segfaults without a
    word (Intel's, once in a whole-suite run at this limit, and at a 4 GiB limit after 13 s). The
    grader cannot tell the second from any other compiler crash; either way the build is stopped,
    every check loses its points for it, and the grading ends with a result, not an error."""
    memory = 3 * 2**28 + 16 * 2**20 * (os.cpu_count() or 1)   # a worker needs ~0.4 GB (+ thread stacks)
    result = grade(NAME, macro_bomb(tmp_path), limits=Limits(memory=memory))
    reason = result["checks"][0]["reason"]
    assert "error" not in result and result["score"] == 0, result
    assert {c["reason"] for c in result["checks"]} == {reason}, result
    assert reason.startswith("the kernel does not build: the compiler crashed while building your kernel ("), reason
    assert "out of memory: the worker may use" in reason or "(SIGSEGV; " in reason, reason


def test_a_build_that_runs_out_of_time_is_a_build_time_out(fake_worker, tmp_path):
    """Before: "stopped after 10 s: the kernel does not finish (an endless loop...)". (A worker
    that hangs in the build stands for the compiler: the macro bomb above, given the memory.)"""
    kernel = tmp_path / "hang.cl"
    kernel.write_text("// fake: hang\n" + STUB)
    result = grade(NAME, kernel, limits=Limits(build=1))
    assert {c["reason"] for c in result["checks"]} == {
        "the kernel does not build: the build was stopped after 1 s: the compiler did not finish (a macro that "
        "expands without end?)"}
    assert result["seconds"] < 1 + Limits().startup


def children(pid):
    """The processes whose parent is `pid`."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def alive(pid):
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc; the parent-death signal is Linux's")
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL], ids=["SIGTERM", "SIGKILL"])
def test_the_worker_dies_with_the_grader(tmp_path, sig):
    """Before: after SIGTERM or SIGHUP the worker ran on at 97% CPU under PID 1, its folder stayed.
    The worker is killed while it compiles the macro bomb. SIGKILL cannot be handled: the
    parent-death signal kills the worker, only the folder stays."""
    temp = tmp_path / "temp"
    temp.mkdir()
    grader = subprocess.Popen([sys.executable, "-m", "toolkit", "grade", NAME, "--kernel", str(macro_bomb(tmp_path))],
                              cwd=ROOT, env=dict(os.environ, TMPDIR=str(temp)), stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True)
    try:
        end = time.monotonic() + 60
        while not children(grader.pid) and time.monotonic() < end and grader.poll() is None:
            time.sleep(0.1)
        workers = children(grader.pid)
        assert workers, grader.communicate()
        time.sleep(0.5)   # it imports, starts, builds
        grader.send_signal(sig)
        _, err = grader.communicate(timeout=30)
    finally:
        grader.kill()
    end = time.monotonic() + 5
    while any(map(alive, workers)) and time.monotonic() < end:
        time.sleep(0.05)
    assert not any(map(alive, workers))
    if sig == signal.SIGTERM:
        assert grader.returncode == 128 + sig and "Traceback" not in err, err
        assert not list(temp.iterdir())


def test_sigterm_and_sighup_end_the_grading_by_an_exit():
    for sig in (signal.SIGTERM, signal.SIGHUP):
        before = signal.getsignal(sig)
        with pytest.raises(GradingStopped) as stopped:
            with stop_on_signals():
                os.kill(os.getpid(), sig)
                time.sleep(5)
        assert stopped.value.code == 128 + sig and signal.getsignal(sig) == before


@pytest.mark.parametrize("value", ["inf", "1e300", "nan", "-1", "0"])
def test_a_time_limit_that_is_not_a_number_of_seconds_is_refused(value, capsys):
    assert main(["grade", NAME, "--solution", "--time-limit", value]) == 2
    err = capsys.readouterr().err
    assert "--time-limit must be a number of seconds above 0 and at most 3600" in err and "Traceback" not in err


# --- fuzzing -----------------------------------------------------------------------------------

NAMES = st.sampled_from(["common.h", "grader_helper.h", A.replaces, "bdpt.h", "../cl/common.h",
                         "/proc/self/environ", "./x.h", "no_such.h", '"', ""])
INCLUDES = st.builds(lambda hash_, name, tail: f'{hash_}include {name}{tail}',
                     st.sampled_from(["#", " # ", "%:", "??=", "#/**/", "#inc\\\n"]),
                     st.one_of(NAMES.map(lambda n: f'"{n}"'), NAMES.map(lambda n: f"<{n}>"), st.just("F")),
                     st.sampled_from(["", " ", " // c", " /* c */", "\\"]))
MACROS = st.builds(lambda name, value: f"#define {name} {value}", st.from_regex(r"[A-Z_]{1,8}", fullmatch=True),
                   st.sampled_from(["1", '"/proc/self/environ"', "<extend_in_place.h>", "F F", "#x"]))
PRINTFS = st.text(alphabet='{}":,\\ abcdefghijklmnopqrstuvwxyz0123456789-', max_size=80).map(printf)
NOISE = st.sampled_from(["/*", "*/", "//", '"/*"', "'\"'", "\\", "??/", ""])
LINES = st.lists(st.one_of(INCLUDES, MACROS, PRINTFS.map(lambda p: "    " + p), NOISE), max_size=8)


KERNEL = "__kernel void k(__global int* out)\n{\n    int started = 0;\n    out[0] = started;\n}\n"


@settings(max_examples=80, deadline=None, database=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(head=LINES, body=LINES)
def test_fuzz_includes_either_refused_or_read_by_the_compiler_from_no_file(folder, head, body):
    """Random include lines, macros, printfs and comment marks at the top of a kernel and in its
    body: the expansion refuses them with a build error at a line of the student's file, or gives
    a source in which the compiler would include no file. (A small kernel, and common.h as the
    allowed header, so that each example takes a millisecond.)"""
    text = with_lines("\n".join(head) + "\n" + KERNEL, *body)
    try:
        source = expand(folder, text, headers=("common.h",))
    except KernelBuildError as refused:
        assert str(refused).startswith(f"{A.replaces}:")
        return
    assert not file_directives(source), text


@settings(max_examples=100, deadline=None, database=None)
@given(lines=st.lists(st.one_of(st.binary(max_size=60), st.builds(
    lambda fields: report_line("n" * 32, **fields)[:-1],
    st.dictionaries(st.sampled_from(["start", "done", "reason", "seconds", "suspect", "fresh"]),
                    st.one_of(st.none(), st.booleans(), st.floats(), st.sampled_from(["build", "ids", "x"])),
                    max_size=5))), max_size=8))
def test_fuzz_reports_either_accepted_in_order_or_a_protocol_error(lines):
    expected, ended = Expected(["build", "ids", "image"]), []
    for line in lines:
        try:
            report = expected.accept(parse_report(line, "n" * 32))
        except ProtocolError:
            return   # the grader's error: the session ends here
        if "done" in report:
            ended.append(report["done"])
            assert isinstance(report["seconds"], (int, float)) and report["seconds"] >= 0
    assert ended == ["build", "ids", "image"][:len(ended)]


@settings(max_examples=2, deadline=None, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(head=st.lists(st.one_of(INCLUDES, MACROS), max_size=3), body=st.lists(PRINTFS.map(lambda p: "    " + p),
                                                                            min_size=1, max_size=4))
def test_fuzz_full_grades_never_fail_hang_or_beat_the_stub(tmp_path, head, body):
    kernel = tmp_path / "fuzzed.cl"
    kernel.write_text(with_lines("\n".join(head) + "\n" + STUB, *body))
    result = grade(NAME, kernel, time_limit=5)
    assert "error" not in result, result["error"]
    assert result["score"] <= graded(NAME, "stub")["score"] and result["seconds"] < 60, result
