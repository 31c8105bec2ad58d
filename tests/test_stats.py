"""The host-side statistics in toolkit/core/stats.py, which the BSDF chi-square test and the render
z-test share, against closed forms and known values (the tails themselves are scipy.special's)."""
import math

import pytest

from toolkit.core.stats import bonferroni, chi2_sf, normal_two_sided_p, pearson, sidak, student_t_two_sided_p


def test_normal_p_values_match_known_values():
    # the two-sided 5% and 1% points of the normal, both signs, and the erfc form of the tail
    assert normal_two_sided_p(1.959963984540054) == pytest.approx(0.05, rel=1e-12)
    assert normal_two_sided_p(-2.5758293035489004) == pytest.approx(0.01, rel=1e-12)
    for z in (0.0, 0.3, 1.0, 4.0, 8.0, 30.0):
        assert normal_two_sided_p(z) == pytest.approx(math.erfc(z / math.sqrt(2.0)), rel=1e-12, abs=1e-300)
    assert normal_two_sided_p([1.0, -1.0]).shape == (2,)


def test_chi2_tail_matches_closed_forms():
    # dof 2: sf = exp(-x/2); even dof 2n: exp(-x/2) sum_{k<n} (x/2)^k / k!; dof 1: erfc(sqrt(x/2));
    # large dof: the Wilson-Hilferty approximation.
    assert chi2_sf(7.0, 2) == pytest.approx(math.exp(-3.5), rel=1e-12)
    for n in (1, 2, 5, 50, 400):
        for x in (0.2, 2.0, 9.0, n, 2.0 * n, 2.6 * n + 14.0):
            exact = sum(math.exp(-x / 2 + k * math.log(x / 2) - math.lgamma(k + 1)) for k in range(n))
            assert chi2_sf(x, 2 * n) == pytest.approx(exact, rel=1e-10, abs=1e-300), (n, x)
    for x in (2e-4, 0.6, 2.0, 5.0, 20.0):
        assert chi2_sf(x, 1) == pytest.approx(math.erfc(math.sqrt(x / 2)), rel=1e-10)
    assert chi2_sf(0.0, 3) == 1.0 and chi2_sf(-1.0, 3) == 1.0
    for dof, x in ((3000, 3000.0), (3000, 3250.0), (4000, 3800.0)):
        h = 2.0 / (9.0 * dof)
        zscore = ((x / dof) ** (1.0 / 3.0) - (1.0 - h)) / math.sqrt(h)
        assert chi2_sf(x, dof) == pytest.approx(0.5 * math.erfc(zscore / math.sqrt(2.0)), abs=2e-3)


def test_pearson_pools_small_cells_and_rejects_impossible_samples():
    statistic, dof, cells, pooled, message = pearson([10, 2, 1, 8], [10.0, 1.0, 2.0, 9.0])
    # the two cells below 5 are pooled (3 observed, 3 expected) and that pool (still < 5)
    # joins the next smallest cell: cells {1,2,4} (11 vs 12) and {3} (10 vs 10)
    assert (cells, dof, pooled, message) == (2, 1, 3, "")
    assert statistic == pytest.approx((11 - 12) ** 2 / 12)
    assert pearson([1, 9], [0.0, 10.0])[0] == math.inf


def test_student_t_p_values_match_closed_forms():
    # dof 1 is the Cauchy distribution: P(|T| >= t) = 1 - 2 atan(t) / pi;
    # dof 2: P(|T| >= t) = 1 - t / sqrt(2 + t^2). Both sides of the incomplete beta's switch.
    for t in (0.0, 0.05, 0.5, 1.0, 3.0, 40.0, 4000.0):
        assert student_t_two_sided_p(t, 1) == pytest.approx(1.0 - 2.0 * math.atan(t) / math.pi, rel=1e-10)
        assert student_t_two_sided_p(-t, 2) == pytest.approx(1.0 - t / math.sqrt(2.0 + t * t), rel=1e-10)
    # many degrees of freedom: the normal's tail
    assert student_t_two_sided_p(2.0, 10 ** 6) == pytest.approx(float(normal_two_sided_p(2.0)), rel=1e-4)


def test_multiple_comparison_corrections_keep_the_family_rate():
    assert bonferroni(0.01, 100) == pytest.approx(1e-4)
    assert 1.0 - (1.0 - sidak(1e-3, 12)) ** 12 == pytest.approx(1e-3, rel=1e-12)
    assert bonferroni(1e-3, 12) < sidak(1e-3, 12) < 1.1 * bonferroni(1e-3, 12)
