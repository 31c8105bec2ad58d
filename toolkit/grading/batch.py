"""`python -m toolkit course grade SUBMISSIONS --out DIR`: an instructor grades a whole class.

SUBMISSIONS holds one folder per student, named after the student. In it the grader looks for
each assignment's file by the name of the toolkit file it replaces, either where the student
edition keeps it (`<student>/cl/compact.h`) or at the top (`<student>/compact.h`). Every
assignment found is graded with every check (grade.py), the ones the student edition skips
included; one that is missing, or still the untouched stub, scores 0 without being built.

The checks run on hidden inputs: every random mask, size, density and seed that a check draws
comes from the public one and `inputs` together (Context.rng), a number drawn anew for each class
unless given (`--inputs N` grades again on the same ones); the reports and grades.csv say which.
A submission fitted to the inputs of the student's copy then fails where it does not generalise.
(The image z-tests keep their fixed, checked seeds: see checks/mis.py.)

Written into DIR, each file whole or not at all (write_atomically):
  grades.csv           a row per student: each assignment's score, then the total
  reports/<student>.txt  the report of each assignment: every lost point with its reason and hint
A student's folder name is theirs to choose, so it only names a row and a report, after its
characters outside [A-Za-z0-9._-] are replaced; two names that then clash are refused.
"""
import csv
import io
import re
import secrets
from pathlib import Path

from toolkit.core.images import write_atomically
from toolkit.grading import edition
from toolkit.grading.checks import ASSIGNMENTS
from toolkit.grading.grade import grade
from toolkit.grading.report import format_report
from toolkit.grading.runner import TIME_LIMIT


def students(submissions):
    """{report name: folder} of the student folders in `submissions` (symbolic links left out: a
    student's folder is theirs, not a way into another one)."""
    submissions = Path(submissions)
    if not submissions.is_dir():
        raise ValueError(f"no such folder of submissions: {submissions}")
    found = {}
    for folder in sorted(p for p in submissions.iterdir() if p.is_dir() and not p.is_symlink()):
        name = re.sub(r"[^A-Za-z0-9._-]", "_", folder.name).lstrip(".-") or "_"   # no hidden file, no CSV formula
        if name in found:
            raise ValueError(f"the student folders {found[name].name!r} and {folder.name!r} both report as {name!r}: "
                             "rename one")
        found[name] = folder
    if not found:
        raise ValueError(f"{submissions} holds no student folder (one folder per student, with their files)")
    return found


def submitted_file(folder, assignment):
    """The student's file for `assignment` in `folder`, or None."""
    for path in (folder / "cl" / assignment.replaces, folder / assignment.replaces):
        if path.is_file():
            return path
    return None


def grade_student(folder, names, time_limit=TIME_LIMIT, device=None, inputs=0):
    """{assignment: result} for one student (see grade.grade); a result without checks for an
    assignment not submitted or still the stub."""
    results = {}
    for name in names:
        a = ASSIGNMENTS[name]
        path = submitted_file(folder, a)
        if path is None:
            results[name] = _ungraded(a, f"no {a.replaces} (looked for cl/{a.replaces} and {a.replaces})")
        elif path.read_bytes() == (a.folder / a.stub).read_bytes():
            results[name] = _ungraded(a, f"{a.replaces} is still the untouched stub")
        else:
            results[name] = grade(name, path, time_limit=time_limit, device=device, inputs=inputs)
    return results


def _ungraded(a, why):
    return {"assignment": a.name, "file": why, "score": 0, "max": sum(c.points for c in a.checks),
            "checks": [], "missing": why}


def hidden_inputs():
    """A fresh number for the hidden inputs, never 0 (0 is the public inputs)."""
    return 1 + secrets.randbelow(2**31 - 1)


def grade_class(submissions, out, names=None, time_limit=TIME_LIMIT, device=None, progress=print, inputs=None):
    """Grade every student of `submissions` for assignments `names` (all if None); write
    grades.csv and reports/ into `out`, on hidden inputs `inputs` (drawn if None). Returns
    ({student: {assignment: result}}, inputs)."""
    if edition.student():
        raise ValueError("this is the student edition: it lacks the reference solutions that the hidden checks "
                         "compare with; grade the class from the instructor edition")
    names = list(ASSIGNMENTS) if names is None else names
    unknown = [n for n in names if n not in ASSIGNMENTS]
    if unknown or not names:
        raise ValueError(f"no assignment {', '.join(unknown) or '(none given)'}: the assignments are "
                         f"{', '.join(ASSIGNMENTS)}")
    found = students(submissions)
    inputs = hidden_inputs() if inputs is None else inputs
    if not 0 < inputs < 2**31:
        raise ValueError(f"--inputs must be a number from 1 to {2**31 - 1} (0 would be the public inputs)")
    out = Path(out)
    grades = {}
    for i, (student, folder) in enumerate(found.items(), start=1):
        progress(f"[{i}/{len(found)}] {student}")
        grades[student] = grade_student(folder, names, time_limit, device, inputs)
        write_atomically(out / "reports" / f"{student}.txt",
                         lambda tmp, r=grades[student]: Path(tmp).write_text(student_report(student, r, inputs)))
    write_atomically(out / "grades.csv", lambda tmp: Path(tmp).write_text(grades_csv(grades, names, inputs)))
    return grades, inputs


def student_report(student, results, inputs):
    parts = [f"# {student}", f"graded on hidden inputs {inputs}", ""]
    for result in results.values():
        if "missing" in result:
            parts.append(f"{result['assignment']}: 0/{result['max']}: {result['missing']}")
        else:
            parts.append(format_report(result))
        parts.append("")
    return "\n".join(parts)


def grades_csv(grades, names, inputs):
    """One row per student: each assignment's score (of 100), the total, and whether the grader
    itself failed on some file (those files' reports say which)."""
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(["student"] + names + ["total", "grader_error", "inputs"])
    for student, results in grades.items():
        scores = [results[n]["score"] for n in names]
        writer.writerow([student] + scores + [sum(scores), int(any("error" in r for r in results.values())), inputs])
    return text.getvalue()
