"""`toolkit.render(scene, technique, options)` (issue 41, item 4): one RenderOptions object, each
field described once (toolkit/core/render_options.py), built the same way by the command line
(toolkit/cli/options.py: render_options) and from Python, and checked when it is made."""
import ast
import dataclasses
import inspect

import numpy as np
import pytest

import toolkit
from toolkit import RenderOptions
from toolkit.cli import build_parser
from toolkit.cli.options import render_options
from toolkit.core import render_options as module
from toolkit.core.validate import InputError


def test_the_defaults():
    options = RenderOptions()
    assert (options.spp, options.seed, options.resolution, options.device, options.warp_width) == (16, 0, None,
                                                                                                   None, None)
    assert (options.count_simd, options.progress, options.general, options.time_phases) == (True, False, False, False)
    assert (options.bvh, options.local_size, options.strategy_images, options.lanes) == ("wide", 64, None, None)
    assert options.technique_options == {}


def test_it_is_frozen_and_changed_by_replace():
    options = RenderOptions(spp=4)
    with pytest.raises(dataclasses.FrozenInstanceError):
        options.spp = 8
    assert dataclasses.replace(options, seed=3) == RenderOptions(spp=4, seed=3)


def test_each_field_is_described_once_beside_it():
    """Every field has its own comment on the line(s) above it in the class, and render's docstring
    names none of them (it points at RenderOptions)."""
    lines = inspect.getsource(module).splitlines()
    tree = ast.parse("\n".join(lines))
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "RenderOptions")
    fields = [n for n in cls.body if isinstance(n, ast.AnnAssign)]
    assert [f.target.id for f in fields] == list(module.FIELDS)
    for f in fields:
        assert lines[f.lineno - 2].strip().startswith("#"), f"{f.target.id} has no comment above it"
    assert len(inspect.getdoc(toolkit.render).splitlines()) <= 8


@pytest.mark.parametrize("field, value, message", [
    ("spp", 0, "spp 0 is outside"),
    ("spp", 2.5, "spp must be a whole number"),
    ("seed", -1, "seed -1 is outside"),
    ("resolution", (8,), "resolution must be"),
    ("resolution", (0, 8), "resolution width 0 is outside"),
    ("device", 0, "device must be a string"),
    ("warp_width", 3, "warp_width must be a power of two"),
    ("bvh", "quad", "bvh must be one of binary, wide"),
    ("local_size", 48, "local_size must be a power of two"),
    ("strategy_images", 0, "strategy_images 0 is outside"),
    ("lanes", "maybe", "lanes must be 'on' or 'off'"),
    ("progress", "yes", "progress must be True or False"),
    ("count_simd", 2, "count_simd must be True or False"),
    ("technique_options", [("pass_spp", 4)], "technique_options must be a dict"),
])
def test_a_bad_field_is_an_input_error_that_names_it(field, value, message):
    with pytest.raises(InputError, match=message):
        RenderOptions(**{field: value})
    with pytest.raises(InputError, match=message):     # render checks the same, before any work
        toolkit.render(None, "pt_naive", **{field: value})


def test_values_are_kept_as_render_uses_them():
    options = RenderOptions(spp=np.int64(4), resolution=np.array([8, 6]), count_simd=np.True_)
    assert options.resolution == (8, 6) and type(options.spp) is int and options.count_simd is True
    given = {"pass_spp": 4}
    options = RenderOptions(technique_options=given)
    given["pass_spp"] = 8                                # a copy: the caller's dict may change later
    assert options.technique_options == {"pass_spp": 4}


def test_render_refuses_an_unknown_keyword_and_a_wrong_options_type():
    with pytest.raises(TypeError, match="no render option 'colour'"):
        toolkit.render(None, "pt_naive", spp=1, colour=2)
    with pytest.raises(InputError, match="options must be a RenderOptions"):
        toolkit.render(None, "pt_naive", 16)
    with pytest.raises(InputError, match="technique options given twice"):
        toolkit.render(None, "pt_naive", {"pass_spp": 1}, technique_options={"pass_spp": 2})


def test_the_command_line_and_python_build_equal_options():
    args = build_parser().parse_args(["render", "--spp", "8", "--seed", "3", "--resolution", "16x8",
                                      "--bvh", "binary", "--general", "--lanes", "off", "--no-progress",
                                      "--device", "0:0"])
    assert render_options(args) == RenderOptions(spp=8, seed=3, resolution=(16, 8), bvh="binary", general=True,
                                                 lanes="off", progress=False, device="0:0")
    args = build_parser().parse_args(["compare", "--warp-width", "16", "--resolution", "8x8"])
    assert render_options(args) == RenderOptions(spp=64, resolution=(8, 8), warp_width=16, progress=True)


def test_a_bad_value_on_the_command_line_is_one_error_line(capsys):
    from toolkit.cli import main
    assert main(["render", "--seed", str(2**32), "--resolution", "4x4", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: seed 4294967296 is outside") and "Traceback" not in err


def test_an_options_object_gives_the_same_image_as_keywords(cornell_box):
    options = RenderOptions(spp=2, seed=9, resolution=(8, 6), count_simd=False, technique_options={"pass_spp": 1})
    by_object = toolkit.render(cornell_box, "pt_naive", options)
    by_keywords = toolkit.render(cornell_box, technique="pt_naive", spp=2, seed=9, resolution=(8, 6),
                                 count_simd=False, options={"pass_spp": 1})
    on_top = toolkit.render(cornell_box, "pt_naive", RenderOptions(spp=2, seed=1), seed=9, resolution=(8, 6),
                            count_simd=False, technique_options={"pass_spp": 1})
    assert by_object.image.shape == (6, 8, 3)
    np.testing.assert_array_equal(by_object.image, by_keywords.image)
    np.testing.assert_array_equal(by_object.image, on_top.image)
