"""`python -m toolkit course grade SUBMISSIONS --out DIR`: an instructor grades a whole class.

SUBMISSIONS holds one folder per student, named after the student. In it the grader looks for
each assignment's file by the name of the toolkit file it replaces, either where the student
edition keeps it (`<student>/cl/compact.h`) or at the top (`<student>/compact.h`). Every
assignment found is graded with every check (grade.py), the ones the student edition skips
included; one that is missing, or still the untouched stub, scores 0 without being built.

Written into DIR, each file whole or not at all (write_atomically):
  grades.csv           a row per student: each assignment's score, then the total
  reports/<student>.txt  the report of each assignment: every lost point with its reason and hint
A student's folder name is theirs to choose, so it only names a row and a report, after its
characters outside [A-Za-z0-9._-] are replaced; two names that then clash are refused.
"""
import csv
import io
import re
from pathlib import Path

from toolkit.core import edition
from toolkit.core.images import write_atomically
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


def grade_student(folder, names, time_limit=TIME_LIMIT, device=None):
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
            results[name] = grade(name, path, time_limit=time_limit, device=device)
    return results


def _ungraded(a, why):
    return {"assignment": a.name, "file": why, "score": 0, "max": sum(c.points for c in a.checks),
            "checks": [], "missing": why}


def grade_class(submissions, out, names=None, time_limit=TIME_LIMIT, device=None, progress=print):
    """Grade every student of `submissions` for assignments `names` (all if None); write
    grades.csv and reports/ into `out`. Returns {student: {assignment: result}}."""
    if edition.STUDENT:
        raise ValueError("this is the student edition: it lacks the reference solutions that the hidden checks "
                         "compare with; grade the class from the instructor edition")
    names = list(ASSIGNMENTS) if names is None else names
    unknown = [n for n in names if n not in ASSIGNMENTS]
    if unknown or not names:
        raise ValueError(f"no assignment {', '.join(unknown) or '(none given)'}: the assignments are "
                         f"{', '.join(ASSIGNMENTS)}")
    found = students(submissions)
    out = Path(out)
    grades = {}
    for i, (student, folder) in enumerate(found.items(), start=1):
        progress(f"[{i}/{len(found)}] {student}")
        grades[student] = grade_student(folder, names, time_limit, device)
        write_atomically(out / "reports" / f"{student}.txt",
                         lambda tmp, r=grades[student]: Path(tmp).write_text(student_report(student, r)))
    write_atomically(out / "grades.csv", lambda tmp: Path(tmp).write_text(grades_csv(grades, names)))
    return grades


def student_report(student, results):
    parts = [f"# {student}", ""]
    for result in results.values():
        if "missing" in result:
            parts.append(f"{result['assignment']}: 0/{result['max']}: {result['missing']}")
        else:
            parts.append(format_report(result))
        parts.append("")
    return "\n".join(parts)


def grades_csv(grades, names):
    """One row per student: each assignment's score (of 100), the total, and whether the grader
    itself failed on some file (those files' reports say which)."""
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(["student"] + names + ["total", "grader_error"])
    for student, results in grades.items():
        scores = [results[n]["score"] for n in names]
        writer.writerow([student] + scores + [sum(scores), int(any("error" in r for r in results.values()))])
    return text.getvalue()
