"""Every usable OpenCL implementation on this machine gives the same image (issue 17).

Random numbers are keyed by (seed, pixel, sample, dimension), so two implementations compute the
same paths; only float rounding may differ. How much: implementations differ in float
contraction (a*b+c fused or not: at most half an ulp, 2^-24 relative, per operation) and in the
last ulp of sqrt/sin/cos/exp. A path of up to ~10 bounces runs a few hundred such operations on
its throughput and contribution, so the relative difference stays below ~300 * 2^-24 = 1.8e-5
(measured: 1.2e-5 on PoCL 3.0 against Intel 2026.2); the test allows 1e-4 (~5x that bound), and
an absolute 1e-6 for pixels near black. A rounding difference that flipped a branch (roulette, a
ray grazing an edge) would change a pixel by a whole sample, far beyond this: that would fail.

Each build here also runs with -Werror (tests/conftest.py), so a compiler warning on any
implementation fails the test too.
"""
from dataclasses import replace

import numpy as np
import pytest

import toolkit
from toolkit.opencl.device import candidates
from toolkit.verify.same_image import ACROSS_IMPLEMENTATIONS

from conftest import SCENES, film_error_techniques

IMPLEMENTATIONS = [c for c in candidates() if c.usable and "Oclgrind" not in c.platform.name]


@pytest.mark.parametrize("scene, max_depth", [("cornell_box", None), ("cornell_spheres", None),
                                              ("cornell_box", 8)])
@pytest.mark.parametrize("technique", film_error_techniques())
def test_every_implementation_renders_the_same_image(technique, scene, max_depth):
    """A finite max_depth too: Intel's cross-work-item vectorizer got the compaction-based
    techniques wrong there once (issue 17; lanes are off by default, toolkit/opencl/lanes.py, and
    tests/test_lanes.py compares the images with lanes on and off)."""
    if len(IMPLEMENTATIONS) < 2:
        pytest.skip("only one OpenCL implementation is usable here")
    loaded = toolkit.load_scene(SCENES / scene)
    if max_depth is not None:
        loaded = replace(loaded, max_depth=max_depth)
    images = {c.implementation: toolkit.render(loaded, technique=technique, spp=4, seed=3,
                                               resolution=(16, 16), device=c.selector, progress=False).image
              for c in IMPLEMENTATIONS}
    (first, reference), *others = images.items()
    assert np.all(np.isfinite(reference))
    for name, image in others:
        np.testing.assert_allclose(image, reference, *ACROSS_IMPLEMENTATIONS,
                                   err_msg=f"{technique} on {scene}: {name} against {first}")
