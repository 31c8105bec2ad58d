"""How the worker reports to the grader (worker.py writes, runner.py reads).

The reports travel on a pipe of their own, never on the worker's stdout: OpenCL's printf writes
to stdout, and a kernel that prints lines shaped like a report must not grade itself. (The
worker's stdout is discarded.) Each report is one line of JSON carrying the run's nonce, a random
word the grader gives each worker on its stdin:

    {"nonce": N, "start": CHECK}                     the worker begins CHECK
    {"nonce": N, "done": CHECK, "reason": null or "why it lost its points",
     "seconds": 1.5, "suspect": false}               CHECK is over (suspect: see worker.py)

The grader expects the checks it asked for, in their order: the start of the next one, then its
end. Any other line is the grader's own error (ProtocolError), reported as such; it never changes
a score, never resets a time limit."""
import json
import math

MAX_LINE = 65536    # bytes in one report; the worker cuts a reason to MAX_REASON characters
MAX_REASON = 2000


class ProtocolError(Exception):
    """A line on the report pipe that is not the report the grader expects."""


def report_line(nonce, **fields):
    """One report as the bytes the worker writes (a line of JSON)."""
    if isinstance(fields.get("reason"), str):
        fields["reason"] = one_line(fields["reason"])
    return (json.dumps(dict(fields, nonce=nonce)) + "\n").encode()


def one_line(text):
    """`text` on one line of at most MAX_REASON characters, as the report shows it."""
    text = " ".join(text.split())
    return text if len(text) <= MAX_REASON else text[:MAX_REASON - 3] + "..."


def parse_report(line, nonce):
    """The report in `line` (bytes, without its newline): {"start": name} or {"done": name,
    "reason", "seconds", "suspect"}, checked field by field. Raises ProtocolError otherwise."""
    if len(line) > MAX_LINE:
        raise ProtocolError(f"a report of {len(line)} bytes (at most {MAX_LINE})")
    try:
        report = json.loads(line.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        raise ProtocolError(f"a line that is not JSON: {_shown(line)}") from None
    if not isinstance(report, dict) or report.get("nonce") != nonce:
        raise ProtocolError(f"a line without this run's nonce: {_shown(line)}")
    if set(report) == {"nonce", "start"} and isinstance(report["start"], str):
        return {"start": report["start"]}
    if set(report) == {"nonce", "done", "reason", "seconds", "suspect"} and _valid_done(report):
        return {key: report[key] for key in ("done", "reason", "seconds", "suspect")}
    raise ProtocolError(f"a report of the wrong shape: {_shown(line)}")


def _valid_done(report):
    seconds = report["seconds"]
    return (isinstance(report["done"], str) and isinstance(report["suspect"], bool)
            and (report["reason"] is None or isinstance(report["reason"], str))
            and isinstance(seconds, (int, float)) and not isinstance(seconds, bool)
            and math.isfinite(seconds) and seconds >= 0)


def _shown(line):
    text = line[:120].decode("utf-8", "replace")
    return repr(text + ("..." if len(line) > 120 else ""))


class Expected:
    """What the grader expects next from one worker that runs `checks` in order: the start of the
    next check, then its end. accept() returns the report, or raises ProtocolError."""

    def __init__(self, checks):
        self.checks = list(checks)
        self.running = None   # the check that started and has not ended
        self.ended = 0        # checks that ended in this worker

    def accept(self, report):
        if "start" in report:
            wanted = self.checks[self.ended] if self.ended < len(self.checks) else None
            if self.running is not None or report["start"] != wanted:
                raise ProtocolError(f"the start of {report['start']!r} while "
                                    + (f"{self.running!r} runs" if self.running else f"expecting {wanted!r}"))
            self.running = report["start"]
        else:
            if report["done"] != self.running:
                raise ProtocolError(f"the end of {report['done']!r} while "
                                    + (f"{self.running!r} runs" if self.running else "no check runs"))
            self.running, self.ended = None, self.ended + 1
        return report
