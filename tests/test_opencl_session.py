"""Issue 41, check 2: no module-level mutable cache is left in toolkit/opencl. What the OpenCL layer
remembers in a process (contexts and queues, probe verdicts, the kernel cache's problems, the steps
done once) lives in one Session (toolkit/opencl/session.py) that a test can see and reset."""
import ast
from pathlib import Path

import pytest

from toolkit.opencl import device, session as session_module
from toolkit.opencl.session import Session, reset_session, session

OPENCL = Path(__file__).resolve().parent.parent / "toolkit" / "opencl"
CONTAINERS = (ast.Dict, ast.List, ast.Set, ast.DictComp, ast.ListComp, ast.SetComp)
CONTAINER_CALLS = {"dict", "list", "set", "defaultdict", "OrderedDict", "Counter", "deque"}
CACHES = {"cache", "lru_cache", "cached_property"}


def _called_name(node):
    """`f` of f(...), f, module.f(...) or module.f; else None."""
    node = node.func if isinstance(node, ast.Call) else node
    return node.id if isinstance(node, ast.Name) else node.attr if isinstance(node, ast.Attribute) else None


def module_level_state(source):
    """(line, what) for each module-level cache of a module's source: an assignment of a dict, list
    or set (a literal, a comprehension or a call that makes one), and each function or class
    decorated with functools' cache or lru_cache."""
    found = []
    for node in ast.parse(source).body:
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and node.value is not None:
            value = node.value
            if isinstance(value, CONTAINERS) or (isinstance(value, ast.Call) and _called_name(value) in CONTAINER_CALLS):
                found.append((node.lineno, ast.unparse(node)[:60]))
        elif isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            found += [(d.lineno, f"@{ast.unparse(d)} {node.name}") for d in node.decorator_list
                      if _called_name(d) in CACHES]
    return found


@pytest.mark.parametrize("path", sorted(OPENCL.glob("*.py")), ids=lambda p: p.name)
def test_no_module_of_toolkit_opencl_keeps_a_cache_of_its_own(path):
    found = module_level_state(path.read_text(encoding="utf-8"))
    assert not found, f"{path.name}: module-level state; keep it in toolkit/opencl/session.py's Session: {found}"


def test_the_check_finds_each_kind():
    source = ("from functools import cache, lru_cache\nimport functools\n"
              "_seen = {}\nnotes: dict = dict()\n_said = set()\nhandles = []\nsquares = [i * i for i in range(3)]\n"
              "NAMES = ('a', 'b')\ncurrent = None\n"
              "@lru_cache(maxsize=None)\ndef a(): pass\n@cache\ndef b(): pass\n@functools.cache\ndef c(): pass\n"
              "def d():\n    local = {}\n")
    assert [line for line, _ in module_level_state(source)] == [3, 4, 5, 6, 7, 10, 12, 14]


def test_the_session_is_made_when_first_asked_for_and_reset(monkeypatch):
    monkeypatch.setattr(session_module, "current", None)
    first = session()
    assert isinstance(first, Session) and session() is first
    reset_session()
    assert session() is not first


def test_a_step_runs_once_per_session(monkeypatch):
    monkeypatch.setattr(session_module, "current", Session())
    runs = []
    assert session().once("step", lambda: runs.append(1) or "done") == "done"
    assert session().once("step", lambda: runs.append(2) or "again") == "done"
    assert runs == [1]


def test_one_queue_per_device_and_a_probe_verdict_per_process(queue):
    """The same queue (and so the same context and its built programs) each time a device is asked
    for, and the probe's verdict kept in the session; a new Session starts both afresh."""
    from toolkit.opencl.device import get_queue
    assert get_queue() is get_queue() is queue
    assert any(q is queue for _, q in session().queues.values())
    usable, _ = device.probe(queue.device)
    assert usable and (True, "") in session().probe_verdicts.values()
    kept = session_module.current
    try:
        session_module.current = Session()
        assert not session().queues and not session().probe_verdicts
        again = get_queue()
        assert again is not queue and again.device == queue.device
    finally:
        session_module.current = kept
    assert get_queue() is queue
