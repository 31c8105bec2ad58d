"""The renderer knows nothing of its users (issue 41): no class is made with `type(name, bases,
attributes)` anywhere in toolkit/ (a variant is a constructor's arguments), and the renderer's
packages (core, opencl, techniques) name no stub, no edition and no grader's hook in their code;
the course's student edition and the grader live in toolkit/grading/."""
import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "toolkit"
RENDERER = ("core", "opencl", "techniques")
GRADERS_WORDS = ("stub", "edition", "source_dir")


def classes_made_with_type(tree):
    """Lines of `type(a, b, c)` calls: the three-argument form makes a class."""
    return [node.lineno for node in ast.walk(tree)
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "type"
            and len(node.args) + len(node.keywords) == 3]


def names_in_code(tree):
    """Every name the code uses or defines (not its comments and docstrings)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Name):
            yield node.lineno, node.id
        elif isinstance(node, ast.Attribute):
            yield node.lineno, node.attr
        elif isinstance(node, (ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef)):
            yield node.lineno, node.name
        elif isinstance(node, ast.arg):
            yield node.lineno, node.arg
        elif isinstance(node, ast.alias):
            yield node.lineno if hasattr(node, "lineno") else 0, node.name


def test_no_class_is_made_with_type_in_the_toolkit():
    found = {path.relative_to(ROOT).as_posix(): lines for path in sorted(PACKAGE.rglob("*.py"))
             if (lines := classes_made_with_type(ast.parse(path.read_text(encoding="utf-8"))))}
    assert not found, f"classes made with type(name, bases, attributes): {found}"


def test_the_check_finds_a_class_made_with_type():
    assert classes_made_with_type(ast.parse("Variant = type('Mlt', (Mlt,), {'x': 1})\nkind = type(x)\n")) == [1]


@pytest.mark.parametrize("package", RENDERER)
def test_the_renderer_names_no_grader_hook(package):
    found = sorted({f"{path.relative_to(ROOT).as_posix()}:{line} {name}"
                    for path in (PACKAGE / package).rglob("*.py")
                    for line, name in names_in_code(ast.parse(path.read_text(encoding="utf-8")))
                    if any(word in name.lower() for word in GRADERS_WORDS)})
    assert not found, f"the renderer names the grader's things: {found}"


def test_the_name_check_finds_one():
    tree = ast.parse("from toolkit.grading import stubs\nclass T:\n    source_dir = None  # a stub\n")
    found = {name for _, name in names_in_code(tree) if any(word in name for word in GRADERS_WORDS)}
    assert found == {"stubs", "source_dir"}
