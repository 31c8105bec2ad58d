"""What Gradescope's `run_autograder` runs, once per submission (gradescope_export.py writes it):

    python -m toolkit.grading.gradescope_run ROOT      # ROOT: /autograder, or $AUTOGRADER_ROOT
    python -m toolkit.grading.gradescope_run --check-solution SOURCE   # setup.sh: the reference scores 100?

Gradescope lays ROOT out as `source/` (the autograder zip, unpacked: autograder.json says which
assignment, on which hidden inputs, and who sees the hidden checks), `submission/` (the student's
files) and `results/`, where this writes `results.json` and nothing else.

The student's file is found as `course grade` finds it (batch.submitted_file: by the name of the
toolkit file it replaces, in `cl/` or at the top) and graded by grade.grade, every check on the
hidden inputs, in the worker subprocess under its limits: the same grading, so the same score,
as `course grade --inputs N` gives offline. A submission never gets a crashed autograder (which
Gradescope shows as an error the student cannot read): no file, the wrong name, the stub, or the
grader's own failure is a results.json with score 0 and what to do. results.json is written by
this process alone, whole or not at all, after the worker is gone; a file of that name in the
submission, or one a kernel tried to write, is overwritten.
"""
import json
import os
import shutil
import sys
import tempfile
import traceback
from itertools import islice
from pathlib import Path

from toolkit.core.images import write_atomically
from toolkit.grading.batch import submitted_file
from toolkit.grading.checks import ASSIGNMENTS
from toolkit.grading.gradescope_results import check_visibility, refused_json, results_json
from toolkit.grading.grade import grade
from toolkit.grading.limits import check_time_limit
from toolkit.grading.report import format_report
from toolkit.grading.runner import Limits
from toolkit.opencl.program import cl_dir

SETTINGS = "autograder.json"   # in source/: what the export chose (gradescope_export.py)
SHOWN_FILES = 10               # submitted files named in a message
MAX_ENTRIES = 10000            # entries of a submission looked at to say what it holds


def read_settings(source):
    """The export's choices in `source`/autograder.json, checked: assignment, inputs,
    hidden_visibility, time_limit (and worker_user, the account the checks run as where the grader
    is root). A ValueError says what is wrong (the zip is not ours, or edited)."""
    try:
        settings = json.loads((Path(source) / SETTINGS).read_text())
    except (OSError, ValueError) as error:
        raise ValueError(f"cannot read {SETTINGS} of the autograder zip: {error}") from None
    if settings.get("assignment") not in ASSIGNMENTS:
        raise ValueError(f"{SETTINGS} names no assignment of this toolkit: {settings.get('assignment')!r}")
    inputs = settings.get("inputs")
    if not isinstance(inputs, int) or isinstance(inputs, bool) or not 0 < inputs < 2**31:
        raise ValueError(f"{SETTINGS}: the hidden inputs' number must be from 1 to {2**31 - 1}")
    check_visibility(settings.get("hidden_visibility"))
    check_time_limit(settings.get("time_limit"))
    if not isinstance(settings.get("worker_user"), (str, type(None))):
        raise ValueError(f"{SETTINGS}: worker_user must be a user's name or null")
    return settings


def find_file(submission, a):
    """(the student's file for assignment `a` in folder `submission`, None) or (None, what to do)."""
    path = submitted_file(submission, a)
    if path is not None:
        return path, None
    found = submission.rglob("*") if submission.is_dir() else iter(())
    files = sorted(str(p.relative_to(submission)) for p in islice(found, MAX_ENTRIES) if p.is_file())
    wanted = (f"This assignment ({a.name}: {a.title}) grades {a.replaces}, the file you wrote from the stub "
              f"{a.stub}; it is built in place of the toolkit's cl/{a.replaces}.")
    if not files:
        return None, f"Your submission holds no file. {wanted} Upload it (at the top, or in cl/) and submit again."
    nested = [f for f in files if Path(f).name == a.replaces]
    if nested:
        return None, (f"Your {a.replaces} is at {nested[0]}: upload the file itself, at the top of your submission "
                      f"or in cl/, not a folder that holds it. {wanted}")
    others = {other.replaces: other.name for other in ASSIGNMENTS.values() if other is not a}
    wrong = [f"{Path(f).name} is the file of assignment {others[Path(f).name]}, not of this one"
             for f in files if Path(f).name in others]
    shown = ", ".join(files[:SHOWN_FILES]) + (f" and {len(files) - SHOWN_FILES} more" if len(files) > SHOWN_FILES
                                               else "")
    return None, (f"Your submission has no {a.replaces} (looked at the top and in cl/); it holds: {shown}. "
                  + (f"{'; '.join(wrong)}. " if wrong else "")
                  + f"{wanted} Name your file {a.replaces} and submit again.")


def worker_limits(settings):
    """The worker's limits: as the settings' worker_user (setup.sh made it) where this runs as root,
    as in Gradescope's container; as this user otherwise (a try on an instructor's machine)."""
    user = settings.get("worker_user")
    return Limits(user=user if user and os.geteuid() == 0 else None)


def grade_submission(root, settings, limits=None):
    """(results.json's content, the grade's result or None) for the submission in `root`."""
    a = ASSIGNMENTS[settings["assignment"]]
    path, problem = find_file(Path(root) / "submission", a)
    if problem:
        return refused_json(a.name, problem), None
    stub = a.folder / a.stub
    # (a link, or a file of another size, is not the stub: grade() refuses what it must unread)
    if not path.is_symlink() and path.stat().st_size == stub.stat().st_size and path.read_bytes() == stub.read_bytes():
        return refused_json(a.name, f"Your {a.replaces} is still the untouched stub: nothing to grade yet. "
                                    f"Write the assignment (its handout: tutorials/assignments/{a.name}/README.md), "
                                    f"check it with `python -m toolkit grade {a.name} --kernel cl/{a.replaces}` "
                                    "in your copy, and submit again."), None
    if limits is None:
        limits = worker_limits(settings)
    result = grade(a.name, path, time_limit=settings["time_limit"], limits=limits, inputs=settings["inputs"])
    result["file"] = a.replaces   # the student's name for it, not the container's path
    return results_json(result, settings["hidden_visibility"]), result


def run(root, limits=None):
    """Grade the submission in `root` and write `root`/results/results.json. Returns the exit status:
    0 whenever results.json was written, whatever the submission (Gradescope reads it either way)."""
    root = Path(root)
    try:
        settings = read_settings(root / "source")
        results, result = grade_submission(root, settings, limits)
        print(format_report(result) if result else results["output"], flush=True)   # for the instructor
    except Exception:   # the grader's own failure: the student still gets a result they can read
        print(traceback.format_exc(), flush=True)
        results = {"score": 0, "stdout_visibility": "hidden",
                   "output": "The autograder failed on this submission before it graded it (not your file's doing, "
                             "as far as it can tell): submit again, and if it happens again tell your instructor, "
                             "who sees the reason in the autograder's output."}
    write_atomically(root / "results" / "results.json",
                     lambda tmp: Path(tmp).write_text(json.dumps(results, indent=1) + "\n"))
    return 0


def check_solution(source):
    """Grade the reference solution as a submission, with the settings in folder `source` (the
    zip's, unpacked): setup.sh does, when Gradescope builds the image, which then fails unless it
    scores 100. Returns the exit status."""
    with tempfile.TemporaryDirectory(prefix="autograder-check-") as root:
        root = Path(root)
        for folder in ("source", "submission", "results"):
            (root / folder).mkdir()
        shutil.copyfile(Path(source) / SETTINGS, root / "source" / SETTINGS)
        a = ASSIGNMENTS[read_settings(root / "source")["assignment"]]
        shutil.copyfile(cl_dir() / a.replaces, root / "submission" / a.replaces)
        run(root)
        score = json.loads((root / "results" / "results.json").read_text())["score"]
    print(f"the reference solution scores {score}", flush=True)
    return 0 if score == 100 else 1


def main(argv):
    if len(argv) == 2 and argv[0] == "--check-solution":
        return check_solution(argv[1])
    if len(argv) != 1 or argv[0].startswith("-"):
        print("usage: python -m toolkit.grading.gradescope_run ROOT (Gradescope's /autograder)\n"
              "       python -m toolkit.grading.gradescope_run --check-solution SOURCE", file=sys.stderr)
        return 2
    return run(argv[0])


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
