"""A technique's parts do not hold the technique (issue 41): BDPT's evaluator and its connect
phase get a BdptContext (kernels, memory, SIMD recorder, compactor), the path tracers' parts get
what they use, so each can be changed, tested and reused alone. Checked on live objects: after a
render, nothing reachable from a technique's attributes leads back to a Technique. And every
technique renders through the same loop (Technique.render), overriding its passes, not the loop."""
import types

import pytest

from toolkit.opencl.device_scene import DeviceScene
from toolkit.techniques import TECHNIQUES
from toolkit.techniques.base import Technique


def techniques_reachable(root):
    """Paths (attribute names) from root's attributes to a Technique: through objects with
    attributes, containers and bound methods (numpy's and OpenCL's objects hold none)."""
    found, seen = [], {id(root)}
    stack = [(value, name) for name, value in vars(root).items()]
    while stack:
        value, path = stack.pop()
        if isinstance(value, Technique):
            found.append(path)
            continue
        if id(value) in seen:
            continue
        seen.add(id(value))
        if hasattr(value, "__self__") and hasattr(value, "__func__"):          # a bound method
            stack.append((value.__self__, f"{path}.__self__"))
        elif isinstance(value, dict):
            stack += [(v, f"{path}[{k!r}]") for k, v in value.items()]
        elif isinstance(value, (list, tuple, set)):
            stack += [(v, f"{path}[{i}]") for i, v in enumerate(value)]
        elif (hasattr(value, "__dict__") and not isinstance(value, (type, types.ModuleType))
              and not type(value).__module__.startswith(("pyopencl", "numpy"))):
            stack += [(v, f"{path}.{k}") for k, v in vars(value).items()]
    return found


@pytest.mark.parametrize("name", sorted(TECHNIQUES))
def test_no_part_of_a_technique_holds_the_technique(queue, cornell_box, name):
    options = {"chains": 64} if name == "mlt" else {}
    tech = TECHNIQUES[name](queue, DeviceScene(queue, cornell_box), **options)
    tech.render(8, 8, 2, seed=1)
    assert techniques_reachable(tech) == [], f"{name}: parts that reach a technique"


def test_the_check_finds_a_part_that_holds_its_technique():
    class Part:
        def __init__(self, tech):
            self.tech = tech

    tech = Technique.__new__(Technique)
    tech.part = {"evaluator": [Part(tech)]}
    assert techniques_reachable(tech) == ["part['evaluator'][0].tech"]


@pytest.mark.parametrize("name", sorted(TECHNIQUES))
def test_every_technique_renders_through_the_same_loop(name):
    cls = TECHNIQUES[name]
    assert cls.render is Technique.render, f"{name} overrides render"
    assert cls.run_pass is not Technique.run_pass, f"{name} has no run_pass"
