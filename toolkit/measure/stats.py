"""The statistics behind the toolkit's tests, with numpy and the standard library only (no scipy).

Two checks use them: `reference.z_test` (a render against its reference, pixel by pixel) and
`bsdf_check.chi2_test` (sampled BSDF directions against the pdf). Both need the tail of a
distribution and a correction for testing many things at once:

- tails: the normal (via erfc), Student's t (through the regularized incomplete beta function)
  and the chi-square (through the regularized upper incomplete gamma function). Both special
  functions are the Numerical Recipes methods (Press et al., 3rd ed., sec. 6.2 and 6.4): a
  power series or a continued fraction, and every continued fraction here is evaluated by
  one function, `continued_fraction` (modified Lentz, NR sec. 5.2);
- multiple comparisons: Bonferroni (alpha / N, any dependence) and Sidak (exact for
  independent tests);
- Pearson's chi-square statistic with Mitsuba's pooling of cells with small expected counts.
"""
import math

import numpy as np

TINY = 1e-300   # stands in for a zero denominator in the Lentz recurrences


def continued_fraction(b0, terms, eps=3e-16, max_iter=100000):
    """b0 + a1 / (b1 + a2 / (b2 + ...)) for the pairs (a_j, b_j) that `terms` yields, by the
    modified Lentz method (Numerical Recipes sec. 5.2): stops when a step changes the value
    by less than eps (relative)."""
    f = b0 if abs(b0) > TINY else TINY
    c, d = f, 0.0
    for _, (a, b) in zip(range(max_iter), terms):
        d = b + a * d
        d = 1.0 / (d if abs(d) > TINY else TINY)
        c = b + a / c
        c = c if abs(c) > TINY else TINY
        delta = c * d
        f *= delta
        if abs(delta - 1.0) < eps:
            return f
    raise ArithmeticError("continued fraction did not converge")


def regularized_beta(a, b, x):
    """I_x(a, b), the regularized incomplete beta function (NR sec. 6.4: the continued fraction
    1 / (1 + d1 / (1 + d2 / ...)), for I_x(a, b) or for 1 - I_{1-x}(b, a), whichever converges
    fast)."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    if x < (a + 1.0) / (a + b + 2.0):
        return _beta_by_fraction(a, b, x)
    return 1.0 - _beta_by_fraction(b, a, 1.0 - x)


def _beta_by_fraction(a, b, x):
    def terms():
        m = 0
        while True:
            yield -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1)), 1.0   # d_{2m+1}
            m += 1
            yield m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m)), 1.0              # d_{2m}

    log_front = (math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b)
                 + a * math.log(x) + b * math.log1p(-x))
    return math.exp(log_front) / (a * continued_fraction(1.0, terms()))


def gammq(a, x, eps=1e-15, max_iter=100000):
    """Regularized upper incomplete gamma Q(a, x) = Gamma(a, x) / Gamma(a) (NR sec. 6.2 `gammq`:
    the series for P when x < a + 1, else the continued fraction
    1 / (x + 1 - a - 1 (1 - a) / (x + 3 - a - 2 (2 - a) / ...)) for Q)."""
    if a <= 0.0 or x < 0.0:
        raise ValueError(f"gammq needs a > 0 and x >= 0, got a={a}, x={x}")
    if x == 0.0:
        return 1.0
    log_prefactor = -x + a * math.log(x) - math.lgamma(a)
    if x < a + 1.0:
        ap, term = a, 1.0 / a
        total = term
        for _ in range(max_iter):
            ap += 1.0
            term *= x / ap
            total += term
            if abs(term) < abs(total) * eps:
                break
        else:
            raise ArithmeticError("gammq: series did not converge")
        return max(0.0, 1.0 - total * math.exp(log_prefactor))
    terms = ((-i * (i - a), x + 1.0 - a + 2.0 * i) for i in range(1, max_iter))
    return math.exp(log_prefactor) / continued_fraction(x + 1.0 - a, terms, eps, max_iter)


def normal_two_sided_p(z):
    """Two-sided p-value of a standard normal z (vectorised, via erfc)."""
    z = np.abs(np.asarray(z, np.float64))
    return np.vectorize(math.erfc)(z / math.sqrt(2.0))


def student_t_two_sided_p(t, dof):
    """P(|T| >= |t|) for Student's t with `dof` degrees of freedom: I_{dof/(dof+t^2)}(dof/2, 1/2)."""
    t = np.abs(np.asarray(t, np.float64))
    return np.vectorize(lambda v: regularized_beta(0.5 * dof, 0.5, dof / (dof + v * v)))(t)


def chi2_sf(statistic, dof):
    """P(X >= statistic) for X chi-square distributed with dof degrees of freedom."""
    return gammq(0.5 * dof, 0.5 * max(0.0, statistic))


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
