"""Every technique against the Mitsuba references in scenes/, at reduced resolution.

The reference (256x256) is averaged over blocks to the test resolution; each test pixel is the
mean of `spp` independent samples, whose standard error comes from the sample variance. The
z-test combines that with the reference's standard error, Bonferroni-corrected over all
pixel-channels at alpha = 0.01 (see toolkit/measure/reference.py).

Resolution and sample counts: cornell_spheres lights most of the room through the mirror
sphere, a rare, bright path for a path tracer; below ~10^4 samples per pixel its per-pixel
distribution is so skewed that the sample variance underestimates the error and a z-test is
not valid. Larger test pixels (8x8, each a 32x32 block of the reference) with 131072 samples
each keep the normal approximation honest (mean |z| measured at 0.80-0.86 over six seeds at half
this count, 0.80 expected for a normal z; the image mean then varies by about 0.3%).
BDPT finds those paths by light tracing and connections, at lower variance per sample; its
error comes from independent passes, so its z follows Student's t (toolkit/measure/reference.py).

cornell_bunny (the Stanford bunny scan, 16,000 triangles, in the diffuse box; reference 128x128)
is lit as cornell_box is, without a rare bright path, so it needs no more samples than the box:
half of them, 8192 per test pixel (1024 for BDPT: 16 passes on a CPU, where its t-based z-test wants at
least 11), cost its five tests ~19 s of CPU in all, 62% of the box's time (a bunny sample costs
~1.4x a box sample: its rays visit 25 BVH nodes against 19). Measured over seeds 1-3 and 7: mean
|z| 0.75-0.88, smallest p 9e-5 (BDPT) to 5e-3 against the corrected alpha of 1.3e-5.
"""
import numpy as np
import pytest

import toolkit
from toolkit.measure.reference import reference_at, relative_mean_error, z_test

from conftest import spp_for, film_error_techniques

CASES = {"cornell_box": (16, 16384), "cornell_bunny": (16, 8192), "cornell_spheres": (8, 131072)}


@pytest.mark.parametrize("technique", film_error_techniques())
@pytest.mark.parametrize("scene_name", sorted(CASES))
def test_every_technique_matches_the_mitsuba_reference(technique, scene_name, request):
    scene = request.getfixturevalue(scene_name)
    res, spp = CASES[scene_name]
    result = toolkit.render(scene, technique=technique, spp=spp_for(technique, spp), seed=7, resolution=(res, res))
    ref, ref_err = reference_at(scene, res, res)
    assert result.stats["nonfinite"] == 0 and result.stats["nonfinite_samples"] == 0
    # Image mean per channel within 1%: the mean's own relative standard error here is ~0.1%.
    rel = relative_mean_error(result.image, ref)
    assert np.all(rel < 0.01), f"{technique} {scene_name}: mean off by {rel}"
    test = z_test(result.image, result.stderr, ref, ref_err, alpha=0.01, dof=result.stats["degrees_of_freedom"])
    print(f"{technique} {scene_name}: {test}; mean rel error {np.round(rel, 5)}")
    assert test.passed, str(test)


def test_z_test_detects_a_wrong_image(cornell_box):
    """The z-test is not toothless: a 3% darker image at the same noise fails it."""
    res, spp = 16, 4096
    result = toolkit.render(cornell_box, spp=spp, seed=3, resolution=(res, res))
    ref, ref_err = reference_at(cornell_box, res, res)
    assert z_test(result.image, result.stderr, ref, ref_err).passed
    assert not z_test(result.image * 0.97, result.stderr, ref, ref_err).passed


def test_z_test_refuses_too_few_passes(cornell_box):
    ref, ref_err = reference_at(cornell_box, 8, 8)
    with pytest.raises(ValueError, match="degrees of freedom"):
        z_test(ref + 1.0, ref_err + 1e-3, ref, ref_err, dof=1)
