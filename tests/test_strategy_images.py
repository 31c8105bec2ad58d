"""Per-strategy images of BDPT (toolkit.render(..., strategy_images=K), render --strategies,
toolkit/measure/strategies.py): the MIS-weighted strategy images add up to the BDPT image, and
both connect phases split it the same way."""
import json
import subprocess
import sys

import numpy as np
import pytest

import toolkit
from conftest import ROOT, SCENES
from toolkit.core.validate import InputError
from toolkit.techniques.strategy_images import strategies, strategy_count, strategy_index

BDPT = ("bdpt_naive_connect", "bdpt_parallel_connect")
SIZE, SPP, EDGES = (16, 16), 4, 3     # 3 edges: the sum of longer paths (most of the indirect light) is tested too


@pytest.fixture(scope="module")
def split():
    """{technique: (BDPT image of the normal kernels, strategy render's image, StrategyImages)}, same seed.
    The strategy renders count SIMD figures and the normal ones do not: neither changes the image."""
    out = {}
    for technique in BDPT:
        normal = toolkit.render(SCENES / "cornell_box", technique=technique, spp=SPP, resolution=SIZE,
                                count_simd=False)
        assert normal.strategy_images is None       # only when asked for
        split = toolkit.render(SCENES / "cornell_box", technique=technique, spp=SPP, resolution=SIZE,
                               strategy_images=EDGES)
        assert split.strategy_images.spp == SPP and split.strategy_images.max_edges == EDGES
        out[technique] = (normal.image, split.image, split.strategy_images)
    return out


def test_strategy_numbering_matches_the_list():
    pairs = strategies(EDGES)
    assert len(pairs) == strategy_count(EDGES) and len(set(pairs)) == len(pairs)
    assert [int(strategy_index(s, t, EDGES)) for s, t in pairs] == list(range(len(pairs)))
    assert int(strategy_index(2, 3, EDGES)) == strategy_count(EDGES)   # 4 edges: the longer paths


@pytest.mark.parametrize("technique", BDPT)
def test_weighted_strategy_images_add_up_to_the_bdpt_image(split, technique):
    normal, image, result = split[technique]
    images, longer = result.images()
    total = sum(weighted for weighted, _ in images.values()) + longer
    # The strategy kernels store unweighted values and weights; the host multiplies them in
    # float32 as the normal kernel does, so only the order of float64 (and, for the naive
    # connect's per-sample sums of longer paths, float32) additions differs: 1e-6 relative.
    scale = float(normal.max())
    np.testing.assert_allclose(total, normal, rtol=1e-6, atol=1e-6 * scale)
    np.testing.assert_allclose(image, normal, rtol=1e-6, atol=1e-6 * scale)
    # Not a sum that holds trivially: several strategies and the longer paths each carry light.
    shares = [float(w.sum()) for w, _ in images.values()] + [float(longer.sum())]
    assert sum(share > 0.01 * sum(shares) for share in shares) >= 5


def test_both_connect_phases_split_the_image_the_same_way(split):
    """Same samples, strategies numbered on the device (naive connect) and on the host
    (parallel connect): every strategy image, weighted and not, agrees to rounding."""
    naive, parallel = split["bdpt_naive_connect"][2].images()[0], split["bdpt_parallel_connect"][2].images()[0]
    for st in naive:
        for a, b in zip(naive[st], parallel[st]):
            np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-6 * max(float(b.max()), 1e-30))


def test_unweighted_images_hold_more_than_their_weighted_part(split):
    """A weight is at most 1: each unweighted image is at least its weighted part, and a strategy
    that samples a path badly (s = 0: the eye path must hit the small light) gets a small weight."""
    images, _ = split["bdpt_parallel_connect"][2].images()
    for weighted, unweighted in images.values():
        assert np.all(weighted <= unweighted * (1 + 1e-6) + 1e-12)
    weighted, unweighted = images[(0, 3)]
    assert weighted.sum() < 0.1 * unweighted.sum()


@pytest.mark.parametrize("technique, edges, error", [
    ("pt_naive", 3, "bidirectional"), ("mlt", 3, "bidirectional"), ("bdpt_parallel_connect", 0, "1 .. 10"),
    ("bdpt_parallel_connect", 11, "1 .. 10"), ("bdpt_naive_connect", 2.0, "whole number"),
    ("bdpt_naive_connect", True, "whole number")])
def test_strategy_images_are_refused_where_they_do_not_apply(technique, edges, error):
    """Checked before any work: a technique without connection strategies, or a bad K."""
    with pytest.raises(InputError, match=error):
        toolkit.render(SCENES / "cornell_box", technique=technique, spp=1, resolution=(4, 4), strategy_images=edges)


def test_the_strategy_kernels_are_not_a_technique_option():
    """strategy_max_edges is render's own argument (strategy_images), not an option."""
    with pytest.raises(InputError, match="unknown option"):
        toolkit.render(SCENES / "cornell_box", technique="bdpt_naive_connect", spp=1, resolution=(4, 4),
                       options={"strategy_max_edges": 3})


def test_render_strategies_command_writes_images_and_json(tmp_path):
    out = tmp_path / "strategies"
    run = subprocess.run([sys.executable, "-m", "toolkit", "render", "--technique", "bdpt_parallel_connect",
                          "--strategies", str(out), "--strategy-edges", "2", "--spp", "1", "--resolution", "8x8",
                          "--no-progress"], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    report = json.loads((out / "strategies.json").read_text())
    assert [(r["s"], r["t"]) for r in report["strategies"]] == strategies(2)
    assert abs(sum(r["variance_share"] for r in report["strategies"]) - 1) < 1e-9
    for s, t in strategies(2):
        assert (out / f"s{s}_t{t}_weighted.exr").is_file() and (out / f"s{s}_t{t}_unweighted.exr").is_file()
    assert "share of variance" in run.stdout
    bad = subprocess.run([sys.executable, "-m", "toolkit", "render", "--technique", "pt_naive", "--strategies",
                          str(out)], cwd=ROOT, capture_output=True, text=True)
    assert bad.returncode == 2 and "bidirectional" in bad.stderr and "Traceback" not in bad.stderr
