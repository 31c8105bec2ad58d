"""The direct dependencies of the toolkit's wheel, for .ci/lowest_versions.

    python wheel_requirements.py WHEEL            print them, one a line (markers kept)
    python wheel_requirements.py --check WHEEL    check that each one installed here is its floor

A floor (`>=X`) is true only where X itself was tested. `--check` runs in the environment that
uv's lowest-direct resolution made: a package installed above its floor means X could not be
installed there (no wheel for this Python, say), so X was not tested and the floor must rise.
"""
import sys
import zipfile
from importlib import metadata

# Floors below the package index's oldest release, tested elsewhere (named here, so that the
# check says so rather than fails).
TESTED_ELSEWHERE = {
    "openimageio": "2.4.7 is Debian 12's, tested by the emulated arm64 run (results/issue37_laptops.md); "
                   "the package index starts at 3.0.3.1",
}


def requirements(wheel):
    """The wheel's Requires-Dist lines that are not for an extra."""
    with zipfile.ZipFile(wheel) as archive:
        name = next(n for n in archive.namelist() if n.endswith(".dist-info/METADATA"))
        text = archive.read(name).decode()
    lines = [line.split(":", 1)[1].strip() for line in text.splitlines() if line.startswith("Requires-Dist:")]
    return [line for line in lines if "extra ==" not in line]


def check(wheel):
    """0 when every applicable requirement is installed at its floor; 1, saying which, otherwise."""
    from packaging.requirements import Requirement
    from packaging.version import Version
    failures = []
    for line in requirements(wheel):
        requirement = Requirement(line)
        if requirement.marker is not None and not requirement.marker.evaluate():
            continue
        floors = [s.version for s in requirement.specifier if s.operator == ">="]
        try:
            installed = metadata.version(requirement.name)
        except metadata.PackageNotFoundError:
            failures.append(f"{requirement.name}: not installed")
            continue
        floor = floors[0] if floors else "(none)"
        same = bool(floors) and Version(installed) == Version(floor)
        note = "" if same else TESTED_ELSEWHERE.get(requirement.name.lower(), "")
        print(f"{requirement.name:30} floor {floor:10} installed {installed:10} "
              + ("ok" if same else f"above the floor: {note}" if note else "ABOVE THE FLOOR"))
        if not same and not note:
            failures.append(f"{requirement.name}: floor {floor}, but {installed} was the oldest that installs here")
    for failure in failures:
        print(f"error: {failure}; raise the floor in setup.cfg to what was tested", file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    if sys.argv[1:2] == ["--check"]:
        raise SystemExit(check(sys.argv[2]))
    print("\n".join(requirements(sys.argv[1])))
