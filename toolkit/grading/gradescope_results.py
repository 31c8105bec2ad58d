"""A graded file as Gradescope's results.json (https://gradescope-autograders.readthedocs.io/en/latest/specs/).

One test per check, in the report's order: its score and maximum, `passed` or `failed`, and as
output the reason and the hint (grade.py), as `course grade` writes them. Who sees a test when
is its `visibility`: a public check's (one the student's copy runs) is `visible` at once; a hidden
check's (it compares with the reference solution: Check.hidden) follows the instructor's choice.
The total is the grade's own score, the same number `course grade` gives the file on the same
inputs (a skipped check, rescaled away there, is a test worth 0 here). The number that drew the
hidden inputs never appears: the student is told only that their inputs are not the copy's.
"""
from toolkit.grading.checks import ASSIGNMENTS

# Gradescope's words for who sees a test: at once, after the due date, after the grades are
# published, never (the instructor always does).
VISIBILITIES = ("visible", "after_due_date", "after_published", "hidden")
SHOWN_WHEN = {"visible": "at once", "after_due_date": "after the due date",
              "after_published": "when your instructor publishes the grades", "hidden": "to your instructor only"}


def check_visibility(value):
    """`value` if it is one of Gradescope's visibilities; a ValueError naming them otherwise."""
    if value not in VISIBILITIES:
        raise ValueError(f"--hidden-visibility must be one of {', '.join(VISIBILITIES)}, got {value!r}")
    return value


def results_json(result, hidden_visibility="after_due_date"):
    """Gradescope's results for `result`, what grade.grade returns for one file."""
    a = ASSIGNMENTS[result["assignment"]]
    hidden = {c.name for c in a.checks if c.hidden}
    tests = [_test(row, row["name"] in hidden, hidden_visibility) for row in result["checks"]]
    return {"score": result["score"], "execution_time": round(result["seconds"]),
            "output": _summary(result, hidden, hidden_visibility), "stdout_visibility": "hidden", "tests": tests}


def refused_json(assignment, message):
    """Results with score 0 and one visible test saying what to do: no file, the wrong one, the stub,
    or the grader's own failure. Nothing was graded."""
    a = ASSIGNMENTS[assignment]
    total = sum(c.points for c in a.checks)
    return {"score": 0, "output": message, "stdout_visibility": "hidden",
            "tests": [{"name": f"{a.name}: your {a.replaces}", "score": 0, "max_score": total, "status": "failed",
                       "output": message, "visibility": "visible"}]}


def _test(row, hidden, hidden_visibility):
    if row["skipped"]:   # this machine cannot run it: counted neither way (the note says so)
        output = f"{row['reason']} (not counted: the score is rescaled from the checks that ran)"
        score = maximum = 0
    else:
        output = "passed" if row["reason"] is None else f"{row['reason']}\nhint: {row['hint']}"
        score, maximum = row["earned"], row["points"]
    return {"name": f"{row['name']}: {row['what']}", "score": score, "max_score": maximum,
            "status": "passed" if row["reason"] is None else "failed", "output": output,
            "visibility": hidden_visibility if hidden else "visible"}


def _summary(result, hidden, hidden_visibility):
    """The text above the tests: the score, what the checks ran on, and when the hidden ones show."""
    lines = [f"{result['assignment']}: {result['score']}/{result['max']}"]
    if "error" in result:
        lines.append(f"The grader failed on your file ({result['error']}): the checks it did not grade earn 0. "
                     "Submit again; if it happens again, tell your instructor.")
    elif any(r["reason"] and r["reason"].startswith("the kernel does not build") for r in result["checks"]):
        lines.append("Your file does not build, so every check loses its points: fix the compiler's first error "
                     "(each test shows it, at its line of your file) and submit again.")
    lines.append("Every check ran on other inputs than the ones in your copy of the course (the same for every "
                 "submission of your class): a file fitted to your copy's inputs loses points here.")
    hidden_points = sum(r["points"] for r in result["checks"] if r["name"] in hidden)
    if hidden_points and hidden_visibility != "visible":
        lines.append(f"{hidden_points} of the points come from checks that compare with the reference solution "
                     f"(your copy skips them): the score counts them, their results are shown "
                     f"{SHOWN_WHEN[hidden_visibility]}.")
    if result.get("note"):
        lines.append(f"Note: {result['note']}.")
    return "\n".join(lines)
