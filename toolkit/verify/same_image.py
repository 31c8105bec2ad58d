"""Same samples, same image: the checks that how the work is scheduled does not change what is
computed, as library code (`python -m toolkit gpucheck` runs them on any device). The tolerances
below are the only ones: tests/test_strategies.py, tests/test_bdpt.py, tests/test_implementations.py
and tests/test_specialization.py assert with them.

Random numbers are keyed by (seed, pixel, sample, dimension), not by work-item, so every
technique of a family, every work-group size and every stream or pool size computes the same
samples; only the order of float additions may differ. The tolerances say by how much:
- SAME_DEVICE: the path tracers agree to float rounding (queued shadow rays add their part in
  another order): a relative 1e-5, an absolute 1e-6 near black (tests/test_strategies.py);
- SAME_DEVICE_BDPT: naive connect adds a sample's eye-path strategies in float32 on the device,
  parallel connect each one in float64 on the host: a relative 1e-4 (tests/test_bdpt.py);
- ACROSS_IMPLEMENTATIONS: two OpenCL implementations differ in float contraction and in the
  last ulp of sqrt/sin/cos/exp, a few hundred roundings per path: 1e-4 relative
  (tests/test_implementations.py explains the bound). Rarely, such a last-ulp difference
  decides a near tie (a ray grazing an edge, a roulette draw) deep in one path, where it
  changes its pixel by little: between PoCL 3.0 and Intel's runtime, one pixel of 9,216 at
  96x96 and 8 spp (cornell_box, seed 3) differs by 1.4e-4 relative, its sample 3 by 5.6e-4 in
  red only. So across implementations up to FLIPS_ALLOWED of the pixels may exceed the tolerance.
A scheduling bug (a lost or doubled sample, a race) changes pixels by a whole sample, far beyond these.
"""
from dataclasses import dataclass, field

import numpy as np

from toolkit import api   # api.render at each call: a test replaces it to plant a bug

PT_FAMILY = ("pt_naive", "pt_inplace_regen", "pt_compact_regen", "pt_compact_regen/multipass")
BDPT_FAMILY = ("bdpt_naive_connect", "bdpt_parallel_connect", "bdpt_parallel_connect/direct_scatter")
SAME_DEVICE = (1e-5, 1e-6)              # (rtol, atol)
SAME_DEVICE_BDPT = (1e-4, 1e-6)
ACROSS_IMPLEMENTATIONS = (1e-4, 1e-6)
FLIPS_ALLOWED = 1e-3                    # share of pixels, across implementations only


@dataclass
class Check:
    name: str
    passed: bool
    detail: str = ""
    figures: dict = field(default_factory=dict)


def compare_images(name, image, reference, tolerance, flips_allowed=0.0):
    """A Check that `image` equals `reference` within (rtol, atol), both finite, in every pixel
    but at most the share `flips_allowed` of them; the detail gives the worst pixel's difference
    as a share of its allowance."""
    rtol, atol = tolerance
    finite = bool(np.isfinite(image).all() and np.isfinite(reference).all())
    if not finite:
        return Check(name, False, "non-finite pixels", {"worst_share_of_tolerance": float("inf")})
    share = (np.abs(image - reference) / (atol + rtol * np.abs(reference))).max(axis=-1)
    worst, beyond = float(share.max()), int((share > 1.0).sum())
    passed = beyond <= flips_allowed * share.size
    detail = f"worst pixel at {worst:.2g} of the tolerance (rtol {rtol:g}, atol {atol:g})"
    if beyond:
        detail += f"; {beyond} of {share.size} pixels beyond it (allowed: {int(flips_allowed * share.size)})"
    return Check(name, passed, detail, {"worst_share_of_tolerance": worst, "pixels_beyond": beyond})


def same_image_checks(scene, device=None, resolution=(16, 16), spp=2, seed=3, others=(), log=None):
    """Every same-image check on `device` (a selector or None): a list of Check.
    `spp` is for the path tracers; BDPT gets max(1, spp // 8) (a sample costs ~10x).
    `others`: (selector, name) of further OpenCL implementations to compare this device with."""
    bdpt_spp = max(1, spp // 8)

    def image(technique, on=device, **kwargs):
        family_spp = bdpt_spp if technique.startswith("bdpt") else spp
        return api.render(scene, technique=technique, spp=family_spp, seed=seed, resolution=resolution, device=on,
                      count_simd=False, **kwargs).image

    def say(text):
        if log:
            log(text)

    checks = []
    for family, tolerance in ((PT_FAMILY, SAME_DEVICE), (BDPT_FAMILY, SAME_DEVICE_BDPT)):
        say(f"same image: {', '.join(family)}")
        base = image(family[0])
        for name in family[1:]:
            checks.append(compare_images(f"{name} = {family[0]}", image(name), base, tolerance))
    pixels = resolution[0] * resolution[1]
    for name, option, size, tolerance in (
            ("pt_inplace_regen", "stream_size", max(4, pixels * spp // 4), SAME_DEVICE),
            ("pt_compact_regen", "stream_size", max(4, pixels * spp // 4), SAME_DEVICE),
            ("bdpt_parallel_connect", "pool_size", max(4, pixels * bdpt_spp // 4), SAME_DEVICE_BDPT)):
        say(f"same image: {name} at the device's {option} and at {size}")
        checks.append(compare_images(f"{name}: {option} {size} = the device's", image(name, options={option: size}),
                                     image(name), tolerance))
    for name, tolerance in (("pt_compact_regen", SAME_DEVICE), ("bdpt_parallel_connect", SAME_DEVICE_BDPT)):
        say(f"same image: {name} at work-group sizes 32, 64, 256")
        base = image(name, local_size=64)
        for size in (32, 256):
            checks.append(compare_images(f"{name}: local size {size} = 64", image(name, local_size=size), base,
                                         tolerance))
    for selector, implementation in others:
        for name in ("pt_compact_regen", "bdpt_parallel_connect"):
            say(f"same image: {name} on {implementation} and on this device")
            checks.append(compare_images(f"{name}: {implementation} = this device", image(name, on=selector),
                                         image(name), ACROSS_IMPLEMENTATIONS, FLIPS_ALLOWED))
    return checks
