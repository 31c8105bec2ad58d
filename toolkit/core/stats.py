"""The statistics behind the toolkit's tests: the distributions' tails come from scipy (the
functions of scipy.special that scipy.stats calls: `import scipy.stats` alone takes ~0.5 s, which
every `python -m toolkit` would pay); here are only the steps that carry a meaning of their own.

Two checks use them: `reference.z_test` (a render against its reference, pixel by pixel) and
`bsdf_check.chi2_test` (sampled BSDF directions against the pdf, with the chi-square's tail).
Both need a two-sided tail and a correction for testing many things at once:

- two-sided p-values of the normal and of Student's t (the z of a pixel can err either way);
- multiple comparisons: Bonferroni (alpha / N, any dependence) and Sidak (exact for
  independent tests);
- Pearson's chi-square statistic with Mitsuba's pooling of cells with small expected counts
  (scipy.stats.chisquare does not pool).
"""
import math

import numpy as np
from scipy import special


def normal_two_sided_p(z):
    """P(|Z| >= |z|) for a standard normal Z (vectorised): twice the normal's CDF at -|z|."""
    return 2.0 * special.ndtr(-np.abs(np.asarray(z, np.float64)))


def student_t_two_sided_p(t, dof):
    """P(|T| >= |t|) for Student's t with `dof` degrees of freedom (vectorised): twice its CDF
    (scipy.special.stdtr) at -|t|."""
    return 2.0 * special.stdtr(dof, -np.abs(np.asarray(t, np.float64)))


def chi2_sf(statistic, dof):
    """P(X >= statistic) for X chi-square distributed with `dof` degrees of freedom (scipy.special.chdtrc,
    the regularized upper incomplete gamma function Q(dof / 2, statistic / 2))."""
    return float(special.chdtrc(dof, max(0.0, statistic)))


def bonferroni(alpha, tests):
    """Per-test significance such that `tests` tests of true hypotheses all pass with
    probability at least 1 - alpha, however they depend on each other."""
    return alpha / max(tests, 1)


def sidak(alpha, tests):
    """Per-test significance such that `tests` independent tests of true hypotheses all pass
    with probability 1 - alpha."""
    return 1.0 - (1.0 - alpha) ** (1.0 / tests)


def pearson(observed, expected, pool_threshold=5.0):
    """Pearson's statistic over cells after pooling: (statistic, dof, cells, pooled, message).

    As in Mitsuba: cells are sorted by expected count; those below the threshold are merged
    into one pooled cell (if it stays below the threshold it joins the next cell). A cell
    with zero expected count but observed samples makes the test fail outright."""
    observed = np.asarray(observed, np.float64).ravel()
    expected = np.asarray(expected, np.float64).ravel()
    impossible = (expected <= 0.0) & (observed > 0)
    if impossible.any():
        return math.inf, 0, 0, 0, (f"{int(observed[impossible].sum())} samples in "
                                   f"{int(impossible.sum())} cells of zero expected count")
    order = np.argsort(expected, kind="stable")
    obs, exp = observed[order], expected[order]
    statistic, cells, pooled = 0.0, 0, 0
    pooled_obs = pooled_exp = 0.0
    for o, e in zip(obs, exp):
        if e <= 0.0:
            continue
        if e < pool_threshold:
            pooled_obs += o
            pooled_exp += e
            pooled += 1
        elif 0.0 < pooled_exp < pool_threshold:
            pooled_obs += o
            pooled_exp += e
            pooled += 1
        else:
            statistic += (o - e) ** 2 / e
            cells += 1
    if pooled_exp > 0.0:
        statistic += (pooled_obs - pooled_exp) ** 2 / pooled_exp
        cells += 1
    return statistic, cells - 1, cells, pooled, ""


def rmse(image, expected):
    """The root-mean-square error of `image` against `expected` (every pixel and channel)."""
    return float(np.sqrt(np.mean((np.asarray(image) - np.asarray(expected)) ** 2)))
