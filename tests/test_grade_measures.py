"""What the grades measure, without a device (toolkit/grading/instrument.py, grade.py): a macro
cannot hide an atomic or a loop from the instrumented build, and a check this machine cannot
run (a missing tool) is skipped, with the score rescaled and a note that says so."""
import shutil

import pytest

from toolkit.grading import instrument
from toolkit.grading.assignment import NEEDS_REFERENCE, SKIPPED
from toolkit.grading.checks import ASSIGNMENTS
from toolkit.grading.grade import _result, selected_checks

needs_cpp = pytest.mark.skipif(shutil.which("cpp") is None, reason="no C preprocessor")

HIDDEN = """
#define GLUE(a, b) a##b
#define RESERVE(p) GLUE(atomic_, cmpxchg)(p, 0, 1)
#undef atomic_add
int f(volatile __global int* counter, __local int* s) {
    int k = 0;
    while (RESERVE(counter) != 0) k++;
    for (;;) { if (atom_add(counter, 1)) break; }
    again: if (atomic_fetch_add_explicit(s, 1, memory_order_relaxed) > 3) goto again;
    atomic_work_item_fence(CLK_LOCAL_MEM_FENCE, memory_order_relaxed, memory_scope_work_group);
    return k;
}
#define KEPT 3
"""


@needs_cpp
def test_atomics_behind_macros_are_counted_and_fences_are_not():
    includes, code, defines = instrument.preprocessed('#include "common.h"\n' + HIDDEN, {"LOCAL_SIZE": 64})
    assert includes == ['#include "common.h"'] and "#define KEPT 3" in defines and "GLUE" not in code
    counted = instrument.counted_atomics(code)
    for call in ("atomic_cmpxchg(grade_counted(counter)", "atom_add(grade_counted(counter)",
                 "atomic_fetch_add_explicit(grade_counted(s)"):
        assert call in counted.replace(" ", ""), counted
    assert "grade_counted(CLK_LOCAL_MEM_FENCE" not in counted


@needs_cpp
def test_every_loop_of_the_counted_copy_ticks():
    _, code, _ = instrument.preprocessed(HIDDEN, {})
    copy = instrument.counted_copy(code, "f", "f")
    assert copy.startswith("int grade_counted_f(")   # with its return type (-Werror: no implicit int)
    assert copy.count(f"++*{instrument.COUNTER}") == 3   # while, for, goto
    assert f"int* {instrument.COUNTER})" in copy


def test_a_helper_with_a_loop_of_its_own_is_refused():
    code = "int g(int n) { int s = 0; for (int i = 0; i < n; i++) s += i; return s; }\nint f(int n) { return g(n); }"
    with pytest.raises(Exception, match="calls g, which has a loop"):
        instrument.counted_copy(code, "f", "f")


def test_a_skipped_check_is_left_out_and_the_score_rescaled():
    a = ASSIGNMENTS["compaction"]
    reasons = {c.name: None for c in a.checks}
    reasons["races"] = SKIPPED + "this check needs Oclgrind"
    reasons["twice"] = "first call: wrong"
    result = _result(a, "mine.cl", dict(reasons, build=None), {}, None, 1.0)
    rows = {r["name"]: r for r in result["checks"]}
    assert rows["races"]["skipped"] and rows["races"]["hint"] is None and rows["twice"]["hint"]
    assert result["score"] == round(80 * 100 / 90) and "rescaled to 89 of 100" in result["note"]
    assert "races skipped (this check needs Oclgrind)" in result["note"]


def test_the_note_says_why_each_check_was_skipped():
    """The student edition skips a check that compares with the reference solution, which it does
    not hold: the note says so (not "this machine cannot run it"), apart from a missing tool."""
    a = ASSIGNMENTS["compaction"]
    reasons = {c.name: None for c in a.checks}
    reasons["races"] = SKIPPED + "this check needs Oclgrind (an OpenCL simulator), which is not installed here: pip ..."
    for name in ("render", "twice"):
        reasons[name] = SKIPPED + NEEDS_REFERENCE
    note = _result(a, "mine.cl", dict(reasons, build=None), {}, None, 1.0)["note"]
    assert "races skipped (this check needs Oclgrind (an OpenCL simulator), which is not installed here)" in note
    assert "twice, render skipped (it compares with the reference solution: your instructor grades it)" in note
    assert "this machine" not in note and "pip" not in note


@needs_cpp
def test_the_preprocessors_own_macros_stay_out_of_the_instrumented_file():
    # cpp defines __STDC_VERSION__ and others even with -undef; the OpenCL compiler defines its
    # own, and a second #define of one is an error there (every instrumented build failed so)
    _, _, defines = instrument.preprocessed("#define KEPT 3\nint x = KEPT;", {})
    assert defines == "#define KEPT 3"


def test_only_the_checks_asked_for_are_reported_and_the_score_rescaled():
    a = ASSIGNMENTS["compaction"]
    reasons = {"build": None, "scan": "the exclusive scan is wrong", "compact": None}
    result = _result(a, "mine.cl", reasons, {}, None, 1.0, selected_checks(a, ["compact", "scan"]))
    assert [r["name"] for r in result["checks"]] == ["scan", "compact"]   # in the report's order
    assert result["score"] == round(20 * 100 / 35) and "only scan, compact graded" in result["note"]
    with pytest.raises(ValueError, match="no check nonsense: its checks are scan, parallel"):
        selected_checks(a, ["scan", "nonsense"])
