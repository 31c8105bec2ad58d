"""The notebooks of the course's student edition (export.py), and how they go on past a cell that
needs an assignment the student has not written.

A cell whose metadata has `"tags": [..., "solution", ...]` shows an assignment's solution: the
student edition has a markdown cell in its place, with the text of the cell's `"exercise"`
metadata (or a line saying what was removed). No saved output is kept: an output can show a
solution as well as a cell can.

The first cell of a student notebook is a hidden setup cell that calls install(). IPython's
custom exception handlers do not help here: the cell still ends in an error, which stops
nbclient and `Run all`. So install() adds an AST transformer that wraps every later cell in
`try: ... except AssignmentNotWritten`, at the top level (the cell's variables stay global, its
last expression is still shown): the message is printed, the cell ends without error and the
notebook goes on. A later cell that then needs a variable the stopped cell did not set fails with
a NameError; once an assignment is missing, that too is one printed line instead of an error, and
so is any other error of a later cell (it works on what the stopped cell left half made).

A removed solution cell is an exercise too: the names it defined (a function the learner is to
write, say) are handed to install(), and a cell that needs one of them before the learner has
written it says so in one line, as for an assignment."""
import ast

from toolkit.grading.stubs import AssignmentNotWritten

SOLUTION_TAG = "solution"
REMOVED = ("**Exercise.** The cell that was here shows the solution of an assignment: write it yourself "
           "(tutorials/assignments/).")
SETUP_SOURCE = ("# Student edition: a cell that needs an assignment or an exercise you have not written says "
                "so, and the notebook goes on.\nfrom toolkit.grading.notebooks import install\ninstall({names})")


def student_notebook(nb):
    """The student edition of notebook `nb` (nbformat 4, as a dict): solution cells replaced by
    exercises, outputs removed, the setup cell first."""
    cells, exercise_names = [], []
    for cell in nb["cells"]:
        meta = cell.get("metadata", {})
        if SOLUTION_TAG in meta.get("tags", []):
            if cell["cell_type"] == "code":
                exercise_names += [n for n in defined_names(_source(cell)) if n not in exercise_names]
            exercise = {"cell_type": "markdown", "metadata": {"tags": ["exercise"]},
                        "source": meta.get("exercise") or REMOVED}
            if "id" in cell:   # nbformat 4.5: every cell has an id (the removed cell's is free)
                exercise["id"] = cell["id"]
            cells.append(exercise)
            continue
        cell = dict(cell)
        if cell["cell_type"] == "code":
            cell["outputs"], cell["execution_count"] = [], None
        cells.append(cell)
    source = SETUP_SOURCE.format(names=repr(exercise_names) if exercise_names else "")
    setup = {"cell_type": "code", "execution_count": None, "outputs": [], "source": source,
             "metadata": {"tags": ["remove-cell", "student-setup"], "jupyter": {"source_hidden": True}}}
    if any("id" in cell for cell in nb["cells"]):
        setup["id"] = "student-setup"
    return dict(nb, cells=[setup] + cells)


def _source(cell):
    return "".join(cell["source"]) if isinstance(cell["source"], list) else cell["source"]


def defined_names(source):
    """The top-level names that Python `source` defines: functions, classes, assigned variables,
    imports (a cell with IPython syntax that is not Python defines none that we can tell)."""
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return []
    names = []
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.append(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names += [n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)]
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names += [(alias.asname or alias.name).split(".")[0] for alias in node.names]
    return names


_missing = []   # the messages of the assignments (and exercises) found missing in this kernel session
_exercise_names = set()   # what the removed solution cells defined: install() sets it


def report_missing(error):
    """Print what a cell needs (an AssignmentNotWritten), in place of its traceback."""
    _missing.append(str(error))
    print(f"not run: {error}")


def report_name(error):
    """A NameError after an assignment was found missing: the variable a stopped cell did not set.
    Before that, it is a bug of the cell, and is raised, unless it names what an exercise is to define."""
    name = getattr(error, "name", None)
    if name in _exercise_names:
        _missing.append(f"`{name}` is an exercise above, not yet written")
        print(f"not run: this cell needs `{name}`, which an exercise above asks you to write")
        return
    if not _missing:
        raise error
    print(f"not run: this cell needs {error.name if hasattr(error, 'name') else error}, which a cell above "
          f"could not compute ({_missing[-1]})")


def report_failure(error):
    """Any other error after an assignment or exercise was found missing: a cell above left its
    results half made (a dict filled for one scene of two, say), so this one fails as well. Said in
    one line that names the error and what it follows from; before anything is missing, raised."""
    if not _missing:
        raise error
    print(f"not run: this cell stopped ({type(error).__name__}: {error}), which follows from a cell above "
          f"that could not compute ({_missing[-1]})")


_LAST = "_toolkit_last_value_"


class _GoOn(ast.NodeTransformer):
    """Wrap a cell's statements in try/except (see the module docstring), its last expression kept."""

    def visit_Module(self, node):
        body = list(node.body)
        if not body:
            return node
        shown = isinstance(body[-1], ast.Expr)
        if shown:
            body[-1] = ast.Assign(targets=[ast.Name(_LAST, ast.Store())], value=body[-1].value)
        handlers = [_handler("AssignmentNotWritten", "report_missing"), _handler("NameError", "report_name"),
                    _handler("Exception", "report_failure")]
        wrapped = [ast.Assign(targets=[ast.Name(_LAST, ast.Store())], value=ast.Constant(None)),
                   ast.Try(body=body, handlers=handlers, orelse=[], finalbody=[])]
        if shown:
            wrapped.append(ast.Expr(ast.Name(_LAST, ast.Load())))
        node.body = wrapped
        return ast.fix_missing_locations(node)


def _handler(exception, function):
    """except <exception> as _toolkit_error_: toolkit.grading.notebooks.<function>(_toolkit_error_)"""
    call = ast.parse(f"__import__('toolkit.grading.notebooks', fromlist=['x']).{function}(_toolkit_error_)").body[0]
    kind = ast.parse(f"__import__('toolkit.grading.stubs', fromlist=['x']).AssignmentNotWritten"
                     if exception == "AssignmentNotWritten" else exception, mode="eval").body
    return ast.ExceptHandler(type=kind, name="_toolkit_error_", body=[call])


def install(exercise_names=(), shell=None):
    """Make IPython (the running kernel's, or `shell`) go on past a cell that needs an unwritten
    assignment, or one of `exercise_names` (what the notebook's exercises are to define)."""
    _exercise_names.update(exercise_names)
    if shell is None:
        from IPython import get_ipython
        shell = get_ipython()
    if shell is not None and not any(isinstance(t, _GoOn) for t in shell.ast_transformers):
        shell.ast_transformers.append(_GoOn())


__all__ = ["AssignmentNotWritten", "install", "student_notebook"]
