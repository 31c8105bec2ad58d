"""Each BSDF of cl/materials.h samples the density its own bsdf_eval reports, that density
integrates as it should, and the sample weights are f |cos| / pdf (toolkit/verify/bsdf_check.py).

All random numbers come from fixed Philox seeds, so every run draws the same samples.
"""
import math

import numpy as np
import pytest

from toolkit.verify.bsdf_check import BsdfChecker, chi2_test, direction, integrate
from toolkit.core.stats import sidak

DIFFUSE = {"type": "diffuse", "reflectance": [0.8, 0.8, 0.8]}
GLOSSY_ALPHAS = (0.1, 0.3, 0.7)
GLOSSY = {a: {"type": "glossy", "reflectance": [0.9, 0.9, 0.9], "alpha": a} for a in GLOSSY_ALPHAS}
INCIDENCE_DEG = (0.0, 45.0, 85.0)   # normal, 45 degrees, grazing (polar angle of wo)
WO_AZIMUTH_DEG = 30.0               # off the bin edges in phi; the BSDFs are isotropic anyway

CHI2_SAMPLES = 1_000_000


def _chi2_cases():
    cases = [("diffuse", DIFFUSE, th) for th in INCIDENCE_DEG]
    cases += [(f"glossy{a}", GLOSSY[a], th) for a in GLOSSY_ALPHAS for th in INCIDENCE_DEG]
    return cases


CHI2_CASES = _chi2_cases()

# The threshold: we want a family-wise false-alarm rate of 1e-3 for the whole set of
# chi-square tests, i.e. a correct BSDF should make any of them fail with probability at most
# 1e-3. The tests use disjoint seeds, hence independent samples, so the Sidak correction
# gives the per-test significance exactly: 1 - (1 - 1e-3)^(1/m) (about 8.3e-5 for m = 12; the
# Bonferroni value 1e-3/m is almost the same). With fixed seeds the outcome is deterministic;
# the correction makes sure the seeds were not picked to pass a marginal test. A wrong
# sampler gives p-values far below this (see test_chi2_detects_a_wrong_pdf).
FAMILY_SIGNIFICANCE = 1e-3
CHI2_SIGNIFICANCE = sidak(FAMILY_SIGNIFICANCE, len(CHI2_CASES))


@pytest.fixture(scope="module")
def checker(queue):
    return BsdfChecker(queue)   # builds cl/bsdf_test.cl once, all four materials compiled in


@pytest.fixture(scope="module")
def sphere_integral(checker):
    """(integral of the pdf, integral of f |cos|) over the sphere, memoised per case."""
    memo = {}

    def get(material, theta):
        key = (repr(material), theta)
        if key not in memo:
            memo[key] = integrate(checker, material, wo(theta))
        return memo[key]
    return get


def wo(theta_deg):
    return direction(theta_deg, WO_AZIMUTH_DEG)


def _ids(cases):
    return [f"{name}-{theta:g}deg" for name, _, theta in cases]


# --- sampling matches the pdf ----------------------------------------------------------------

@pytest.mark.parametrize("case", range(len(CHI2_CASES)), ids=_ids(CHI2_CASES))
def test_chi2_sampled_directions_match_pdf(checker, case):
    name, material, theta = CHI2_CASES[case]
    if name == "glossy0.1" and theta == 0.0:
        # half the samples have z > 0.98: bin the cap z > 0.9 (84% of them) finely; the
        # rest of the sphere and the failed samples form one extra cell
        options = dict(z_range=(0.9, 1.0), res=(40, 96))
    else:
        # the whole sphere, 32 x 96 equal-area bins per hemisphere: a direction below the
        # horizon would land in a cell of zero expected count and fail the test outright
        options = dict(z_range=(-1.0, 1.0), res=(64, 96))
    result = chi2_test(checker, material, wo(theta), n_samples=CHI2_SAMPLES, seed=1000 + case,
                       **options)
    print(f"{name} theta={theta:g}: chi2={result.statistic:.1f} dof={result.dof} "
          f"p={result.p_value:.4g} (pooled {result.pooled} bins)")
    assert not result.message, result.message
    assert result.p_value >= CHI2_SIGNIFICANCE, (
        f"{name} at {theta:g} deg: sampled directions do not follow the pdf: chi2 = "
        f"{result.statistic:.1f} with {result.dof} dof, p = {result.p_value:.3g} < "
        f"{CHI2_SIGNIFICANCE:.3g}")


def test_chi2_detects_a_wrong_pdf(checker):
    """The test has power: samples of alpha = 0.3 against the pdf of alpha = 0.315 (5%), and
    the diffuse sampler against a rough glossy pdf, are rejected by far."""
    wrong = dict(GLOSSY[0.3], alpha=0.315)
    result = chi2_test(checker, GLOSSY[0.3], wo(45.0), n_samples=CHI2_SAMPLES, seed=7,
                       res=(64, 96), eval_material=wrong)
    assert result.p_value < 1e-6 * CHI2_SIGNIFICANCE, result
    result = chi2_test(checker, DIFFUSE, wo(0.0), n_samples=CHI2_SAMPLES, seed=8,
                       res=(64, 96), eval_material=GLOSSY[0.7])
    assert result.p_value < 1e-6 * CHI2_SIGNIFICANCE, result


# --- the pdf integrates properly -------------------------------------------------------------

@pytest.mark.parametrize("theta", INCIDENCE_DEG)
def test_diffuse_pdf_integrates_to_one(sphere_integral, theta):
    pdf_integral, f_cos = sphere_integral(DIFFUSE, theta)
    print(f"diffuse theta={theta:g}: integral of pdf = {pdf_integral:.7f}")
    assert pdf_integral == pytest.approx(1.0, abs=1e-3)
    # white furnace by quadrature: the albedo of a Lambertian surface is its reflectance
    np.testing.assert_allclose(f_cos, DIFFUSE["reflectance"], atol=1e-4)


@pytest.mark.parametrize("alpha", GLOSSY_ALPHAS)
@pytest.mark.parametrize("theta", INCIDENCE_DEG)
def test_glossy_pdf_integral_and_failed_samples(checker, sphere_integral, alpha, theta):
    material = GLOSSY[alpha]
    pdf_integral, _ = sphere_integral(material, theta)
    print(f"glossy alpha={alpha} theta={theta:g}: integral of pdf = {pdf_integral:.7f}")
    # Visible-normal sampling draws a normalised density of microfacet normals; the reflected
    # direction is lost (the sample fails) when it points below the horizon, so the pdf of
    # wi integrates to 1 - P(fail) <= 1. The tolerance covers the quadrature and float32.
    assert pdf_integral <= 1.0 + 1e-5
    if theta == 0.0:
        # At normal incidence the visible normals have density D(m) cos(theta_m), and
        # P(tan^2 theta_m < t) = t / (alpha^2 + t) for GGX; wi stays above the horizon iff
        # theta_m < 45 deg: the integral is exactly 1 / (1 + alpha^2) (0.990 for alpha 0.1).
        assert pdf_integral == pytest.approx(1.0 / (1.0 + alpha * alpha), abs=2e-5)
    n = 1_000_000
    samples = checker.sample(material, wo(theta), n, seed=2000 + int(100 * alpha) + int(theta))
    failed = 1.0 - samples.ok.mean()
    expected = 1.0 - pdf_integral
    sigma = math.sqrt(max(expected * (1.0 - expected), 1.0 / n) / n)
    print(f"  failed fraction {failed:.6f}, expected {expected:.6f} +- {sigma:.6f}")
    assert abs(failed - expected) <= 5.0 * sigma + 1e-5


# --- sample weights agree with eval ----------------------------------------------------------

WEIGHT_CASES = [("diffuse", DIFFUSE, th) for th in INCIDENCE_DEG] + \
               [(f"glossy{a}", GLOSSY[a], th) for a in GLOSSY_ALPHAS for th in INCIDENCE_DEG]


@pytest.mark.parametrize("case", range(len(WEIGHT_CASES)), ids=_ids(WEIGHT_CASES))
def test_sample_weight_is_f_cos_over_pdf(checker, case):
    _, material, theta = WEIGHT_CASES[case]
    s = checker.sample(material, wo(theta), 100_000, seed=3000 + case)
    assert s.ok.mean() > 0.5
    wi, weight, pdf = s.wi[s.ok], s.weight[s.ok], s.pdf[s.ok]
    assert not s.specular.any()
    assert np.all(wi[:, 2] > 0.0), "a successful sample points below the surface"
    np.testing.assert_allclose(np.linalg.norm(wi.astype(np.float64), axis=1), 1.0, atol=2e-6)
    f, eval_pdf = checker.evaluate(material, wo(theta), wi)
    # the sampler reports the pdf that eval gives for the same direction
    np.testing.assert_allclose(pdf, eval_pdf, rtol=2e-6)
    # float32 tolerance: a handful of ulps (the two paths round differently; seen: 3e-7)
    f_cos_over_pdf = f.astype(np.float64) * wi[:, 2:3].astype(np.float64) / eval_pdf[:, None]
    np.testing.assert_allclose(weight, f_cos_over_pdf, rtol=2e-6)


# --- energy ----------------------------------------------------------------------------------

@pytest.mark.parametrize("theta", INCIDENCE_DEG)
def test_diffuse_sample_weight_is_the_reflectance(checker, theta):
    """Every diffuse sample has weight = reflectance, so the furnace estimate is exact."""
    s = checker.sample(DIFFUSE, wo(theta), 100_000, seed=4000 + int(theta))
    assert s.ok.all()
    np.testing.assert_array_equal(s.weight, np.float32(0.8))
    np.testing.assert_allclose(s.weight.astype(np.float64).mean(0), DIFFUSE["reflectance"], rtol=1e-7)


@pytest.mark.parametrize("alpha", GLOSSY_ALPHAS)
@pytest.mark.parametrize("theta", INCIDENCE_DEG)
def test_glossy_creates_no_energy(checker, sphere_integral, alpha, theta):
    material = GLOSSY[alpha]
    n = 1_000_000
    s = checker.sample(material, wo(theta), n, seed=5000 + int(100 * alpha) + int(theta))
    reflectance = np.float32(material["reflectance"][0])
    # weight = R G1(wi) <= R for every sample, failed samples carry 0
    assert s.weight.max() <= reflectance * (1 + 1e-6)
    albedo = s.weight[:, 0].astype(np.float64)
    mean, sigma = albedo.mean(), albedo.std() / math.sqrt(n)
    assert mean <= material["reflectance"][0]
    # and the Monte Carlo albedo agrees with the quadrature of f |cos theta_i| over the sphere
    _, f_cos = sphere_integral(material, theta)
    print(f"glossy alpha={alpha} theta={theta:g}: albedo {mean:.5f} +- {sigma:.5f}, "
          f"quadrature {f_cos[0]:.5f}")
    assert abs(mean - f_cos[0]) <= 5.0 * sigma + 1e-5


# --- specular materials ----------------------------------------------------------------------

@pytest.mark.parametrize("theta,phi", [(0.0, 0.0), (30.0, 10.0), (60.0, 200.0), (89.0, -75.0)])
def test_mirror_reflects_exactly(checker, theta, phi):
    material = {"type": "mirror", "reflectance": [0.9, 0.6, 0.3]}
    w = direction(theta, phi)
    s = checker.sample(material, w, 1000, seed=6000)
    w32 = w.astype(np.float32)
    assert s.ok.all() and s.specular.all()
    np.testing.assert_array_equal(s.wi, np.broadcast_to([-w32[0], -w32[1], w32[2]], s.wi.shape))
    np.testing.assert_array_equal(s.weight, np.broadcast_to(np.float32([0.9, 0.6, 0.3]), s.weight.shape))
    # a delta lobe is never evaluated: eval gives zero f and pdf
    f, pdf = checker.evaluate(material, w, s.wi[:10])
    assert not f.any() and not pdf.any()


def fresnel(cos_i, eta):
    """Unpolarised Fresnel reflectance for relative index eta = n_t / n_i, float64."""
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
    if sin2_t >= 1.0:
        return 1.0
    cos_t = math.sqrt(1.0 - sin2_t)
    r_s = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    r_p = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (r_s * r_s + r_p * r_p)


IOR = 1.5
CRITICAL_DEG = math.degrees(math.asin(1.0 / IOR))   # 41.81 deg
# (angle of incidence, outside?): inside, 20 and 40 deg refract, 45, 60 and 85 are beyond
# the critical angle
DIELECTRIC_CASES = [(th, True) for th in (0.0, 30.0, 60.0, 80.0, 89.0)] + \
                   [(th, False) for th in (0.0, 20.0, 40.0, 45.0, 60.0, 85.0)]


@pytest.mark.parametrize("theta_i,outside", DIELECTRIC_CASES,
                         ids=[f"{'outside' if o else 'inside'}-{t:g}deg" for t, o in DIELECTRIC_CASES])
def test_dielectric_fresnel_and_snell(checker, theta_i, outside):
    material = {"type": "dielectric", "ior": IOR}
    w = direction(theta_i if outside else 180.0 - theta_i, 40.0)
    n = 400_000
    s = checker.sample(material, w, n, seed=7000 + int(theta_i) + (0 if outside else 100))
    assert s.ok.all() and s.specular.all()
    np.testing.assert_array_equal(s.weight, 1.0)     # the choice with probability F cancels F
    w64 = w.astype(np.float32).astype(np.float64)    # what the kernel received
    eta = IOR if outside else 1.0 / IOR             # n_t / n_i
    F = fresnel(abs(w64[2]), eta)
    reflected = np.sign(s.wi[:, 2]) == np.sign(w64[2])
    fraction = reflected.mean()
    sigma = math.sqrt(F * (1.0 - F) / n)
    print(f"{'outside' if outside else 'inside'} {theta_i:g} deg: reflected {fraction:.5f}, "
          f"Fresnel {F:.5f} +- {sigma:.5f}")
    # 5 binomial standard errors; the float32 Fresnel and the 24-bit uniforms add < 1e-6
    assert abs(fraction - F) <= 5.0 * sigma + 1e-6
    if not outside and theta_i > CRITICAL_DEG:
        assert reflected.all(), "total internal reflection must always reflect"
    w32 = w.astype(np.float32)
    np.testing.assert_array_equal(s.wi[reflected],
                                  np.broadcast_to([-w32[0], -w32[1], w32[2]], s.wi[reflected].shape))
    t = s.wi[~reflected].astype(np.float64)
    if len(t):
        assert np.all(np.sign(t[:, 2]) == -np.sign(w64[2]))          # the opposite side
        np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-6)
        sin_i, sin_t = math.hypot(w64[0], w64[1]), np.hypot(t[:, 0], t[:, 1])
        np.testing.assert_allclose(sin_t * eta, sin_i, atol=1e-6)       # Snell's law
        if sin_i > 0.0:
            # in the plane of incidence, on the far side of the normal
            tangent = -w64[:2] / sin_i
            np.testing.assert_allclose(t[:, :2] / sin_t[:, None], np.broadcast_to(tangent, (len(t), 2)),
                                       atol=1e-5)


def test_dielectric_total_internal_reflection_beyond_critical_angle(checker):
    material = {"type": "dielectric", "ior": IOR}
    for theta_i in (CRITICAL_DEG + 0.5, 50.0, 70.0, 89.5):
        w = direction(180.0 - theta_i, -120.0)
        s = checker.sample(material, w, 20_000, seed=8000 + int(theta_i))
        assert s.ok.all()
        assert np.all(s.wi[:, 2] < 0.0), f"light escaped at {theta_i:.2f} deg from inside"
        w32 = w.astype(np.float32)
        np.testing.assert_array_equal(s.wi, np.broadcast_to([-w32[0], -w32[1], w32[2]], s.wi.shape))
