"""The toolkit's packages import in one direction (docs/layout.md): each package imports only
the packages below it, so a learner can read the floors from the ground up and no import circle
can form between them. The rule is read from the source, every import statement in every file,
including those inside functions."""
import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "toolkit"

# Each package and the packages it may import. The product is core <- opencl <- techniques <- api;
# on top of api stand measurement (errors against references, bench, the study), the peers and the
# checks side by side (DESIGN.md): neither peers nor verify imports measure, and what they share
# (the statistics) lives in core (core/stats.py). verify's cross-check uses a peer (Embree); grading
# uses the measurements and the checks' known targets (verify/mlt_toy.py for the MLT assignment);
# cli, __main__ and the package's face (toolkit/__init__.py) may import everything.
BELOW = {
    "core": set(),
    "opencl": {"core"},
    "techniques": {"core", "opencl"},
    "api": {"core", "opencl", "techniques"},
    "measure": {"core", "opencl", "techniques", "api"},
    "peers": {"core", "opencl", "techniques", "api"},
    "verify": {"core", "opencl", "techniques", "api", "peers"},
    "grading": {"core", "opencl", "techniques", "api", "measure", "verify"},
    # the live demo (toolkit/demo/): renders through the techniques, measures against references
    "demo": {"core", "opencl", "techniques", "api", "measure"},
}
TOP = {"cli", "__main__", "__init__"}


def package_of(path):
    """The package of a file under toolkit/: its folder, or its own name for a top-level module."""
    rel = path.relative_to(PACKAGE)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def toolkit_imports(path):
    """(line, imported toolkit module) for every import statement in `path`."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    module = ".".join(("toolkit", *path.relative_to(PACKAGE).with_suffix("").parts))   # a face ends in .__init__
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "toolkit":
                    yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:   # relative: resolve against this file's package
                package = module.split(".")[:-1]          # toolkit.core.scene -> toolkit.core
                base = package[:len(package) - node.level + 1]
                name = ".".join([*base, node.module] if node.module else base)
            else:
                name = node.module or ""
            if name == "toolkit":   # `from toolkit import api` is a module; `import render`, the face
                for alias in node.names:
                    module = PACKAGE / alias.name
                    is_module = module.is_dir() or module.with_suffix(".py").is_file()
                    yield node.lineno, f"toolkit.{alias.name}" if is_module else "toolkit"
            elif name.split(".")[0] == "toolkit":
                yield node.lineno, name
                for alias in node.names:   # `from toolkit.core import scene` imports toolkit.core.scene
                    yield node.lineno, f"{name}.{alias.name}"


def imported_package(name):
    """The package of an imported toolkit module; bare `toolkit` is the package's face, which
    imports api: a file below it that imports it climbs the floors too."""
    parts = name.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


SOURCES = sorted(PACKAGE.rglob("*.py"))


def test_every_package_is_in_the_rule():
    packages = {package_of(p) for p in SOURCES}
    assert packages - TOP - set(BELOW) == set(), "a package the import rule does not know"


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: p.relative_to(PACKAGE).as_posix())
def test_imports_run_down_the_floors(path):
    own = package_of(path)
    if own in TOP:
        return
    allowed = BELOW[own] | {own}
    known = set(BELOW) | TOP    # `from toolkit.core import scene` also yields toolkit.core.scene: no package
    wrong = sorted({f"line {line}: {name}" for line, name in toolkit_imports(path)
                    if imported_package(name) in known - allowed})
    assert not wrong, f"{path.relative_to(ROOT)} ({own}) may import only {sorted(allowed)}: {wrong}"


def module_graph():
    """toolkit module -> the toolkit modules it imports (as files), for the circle test."""
    modules = {".".join(("toolkit", *p.relative_to(PACKAGE).with_suffix("").parts)).removesuffix(".__init__"): p
               for p in SOURCES}
    graph = {}
    for name, path in modules.items():
        graph[name] = {target for _, target in toolkit_imports(path) if target in modules and target != name}
    return graph


def test_no_import_circle_among_the_modules():
    """A depth-first search for a back edge; package faces (__init__.py) count as modules."""
    graph = module_graph()
    state, circles = {}, []

    def visit(node, trail):
        state[node] = "open"
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                circles.append(trail[trail.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, trail + [nxt])
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])
    # toolkit/__init__.py is the package's face: Python runs it before any submodule, and it
    # imports api for `toolkit.render`. Circles through it are the face, not the architecture;
    # every other circle fails.
    circles = [c for c in circles if "toolkit" not in c]
    assert not circles, "import circles: " + "; ".join(" -> ".join(c) for c in circles)


def test_the_rule_catches_an_upward_import(tmp_path):
    """The checker itself: an import from core into api is reported."""
    fake = PACKAGE / "core" / "__rule_probe__.py"
    try:
        fake.write_text("from toolkit.api import render\n")
        with pytest.raises(AssertionError, match="may import only"):
            test_imports_run_down_the_floors(fake)
        fake.write_text("from toolkit import render\n")     # through the package's face
        with pytest.raises(AssertionError, match="may import only"):
            test_imports_run_down_the_floors(fake)
    finally:
        fake.unlink()


@pytest.mark.parametrize("sibling", ["peers", "verify"])
def test_the_rule_keeps_measure_beside_peers_and_verify(sibling):
    """measure, peers and verify are siblings: an import of measure from either is reported."""
    fake = PACKAGE / sibling / "__rule_probe__.py"
    try:
        fake.write_text("from toolkit.measure.reference import reference_at\n")
        with pytest.raises(AssertionError, match="may import only"):
            test_imports_run_down_the_floors(fake)
    finally:
        fake.unlink()
