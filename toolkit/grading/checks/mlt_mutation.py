"""Assignment 6, Kelemen's mutation for primary-sample-space MLT (tutorials/assignments/mlt_mutation/):
the checks of a student's cl/mlt_mutation.h (mlt_perturb and mlt_mutate; cl/mlt.h, which includes it,
keeps the toolkit's mlt_accept).
Exact checks of the small step on known inputs; tutorial 05's chi-square tests of the chains on
its known target (cl/mlt_test.cl, toolkit/verify/mlt_toy.py); the on-the-fly normalisation b,
the mean f of the large steps, on that target; an MLT image against the reference."""
import numpy as np

from toolkit.core.layout import MLT_CHAIN, MLT_ITERATION, MltMode
from toolkit.grading.assignment import Assignment, CheckFailed
from toolkit.measure.reference import reference_at, relative_mean_error, z_test
from toolkit.opencl import program
from toolkit.techniques import Mlt
from toolkit.techniques.mlt import SMALL_STEP, step_defines
from toolkit.verify import mlt_toy

ASSIGNMENT = Assignment("mlt_mutation", "Kelemen's mutation for MLT: small and large steps", "mlt_mutation.h",
                        "mlt_mutation_stub.cl", ("mlt_mutation_checks.cl",),
                        headers=("common.h", "philox.h", "mlt_proposals.h"))

S2, S1 = SMALL_STEP, SMALL_STEP / 16   # the host's MLT_S2 and MLT_S1 (toolkit/techniques/mlt.py step_defines)
_DEFINES = {"MLT_MAX_DIMS": mlt_toy.MAX_DIMS, **step_defines(SMALL_STEP)}
_FRESH = -1.0   # MLT_FRESH (cl/mlt_proposals.h)
# A chi-square test fails at p < ALPHA. Pearson's statistic of N independent final states (one per
# chain) over the pooled cells is chi-square distributed with cells - 1 degrees of freedom when
# the chains sample the target, so a right mutation fails with probability ALPHA on a seed nobody
# checked. The seeds are fixed and checked (right solution passes), even for hidden inputs.
ALPHA = 1e-3
# The normalisation's z bound: two-sided alpha 1e-3 of the normal (the mean of ~20k large steps' f).
Z_BOUND = 3.29


@ASSIGNMENT.builds
def build(c):
    """Everything the checks build: the grader kernel, the toy target with the student's file and
    the toolkit's, and (if it runs) the MLT technique for the image."""
    c.build("mlt_mutation_checks.cl", _DEFINES)
    for directory in (c.sources(), c.reference_sources()):
        program.build(c.queue, "mlt_test.cl", _DEFINES, directory=directory)
    if c.runs("image"):
        _mlt(c)


def _kelemen(u, r):
    """Kelemen's small step in float64: the sign from r < 1/2, the size s2 exp(-log(s2/s1) v)."""
    u, r = np.asarray(u, np.float64), np.asarray(r, np.float64)
    up = r < 0.5
    v = np.where(up, 2 * r, 2 * r - 1)
    dv = S2 * np.exp(-np.log(S2 / S1) * v)
    return np.where(up, u + dv, u - dv) % 1.0


def _perturb(c, u, r):
    built = c.build("mlt_mutation_checks.cl", _DEFINES)
    n = len(u)
    out = c.buffer(np.full(n, np.nan, np.float32))
    program.launch(c.queue, program.kernel(built, "grade_mlt_perturb"), n, c.buffer(u.astype(np.float32)),
                   c.buffer(r.astype(np.float32)), np.int32(n), out)
    return c.read(out, np.float32, n)


def _circular(a, b):
    d = np.abs(np.asarray(a, np.float64) - b) % 1.0
    return np.minimum(d, 1.0 - d)


_TOLERANCE = 2e-6   # float32 rounding of u +- dv near 1 (6e-8) and of exp (a few ulp of dv <= 1/16)


def _first_wrong(c, u, r, got):
    wrong = np.flatnonzero(~(_circular(got, _kelemen(u, r)) <= _TOLERANCE))
    if not len(wrong):
        return None
    k = wrong[0]
    still = " (your step does not move u)" if np.all(got == u.astype(np.float32)) else ""
    return (f"mlt_perturb(u={u[k]:.6f}, r={r[k]:.6f}) = {got[k]:.6f}, Kelemen's step gives "
            f"{_kelemen(u[k], r[k]):.6f} ({len(wrong)} of {len(u)} wrong){still}")


@ASSIGNMENT.check("perturb", 15, "mlt_perturb away from the edges: u +- s2 exp(-log(s2/s1) v), the sign from r",
                  "one uniform r gives both the direction (r < 1/2) and v, uniform in [0, 1) on either side; "
                  "the size falls exponentially from s2 to s1")
def _check_perturb(c):
    rng = c.rng(61)
    u = rng.uniform(S2, 1 - S2, 4096)
    r = rng.random(4096)
    problem = _first_wrong(c, u, r, _perturb(c, u, r))
    if problem:
        raise CheckFailed(problem)


@ASSIGNMENT.check("symmetric", 10, "the step is symmetric: r and r + 1/2 move u by the same size in opposite "
                                   "directions, between s1 and s2", "Metropolis-Hastings with a = min(1, f(y)/f(x)) "
                  "needs T(x -> y) = T(y -> x): +dv and -dv must be equally likely, with the same size distribution")
def _check_symmetric(c):
    rng = c.rng(62)
    u = rng.uniform(S2, 1 - S2, 2048)
    r = rng.random(2048) * 0.5
    up, down = (_perturb(c, u, r) - u.astype(np.float32)), (_perturb(c, u, r + 0.5) - u.astype(np.float32))
    size = np.abs(up)
    bad = np.flatnonzero(~((np.abs(up + down) <= _TOLERANCE) & (size >= S1 * (1 - 1e-4)) & (size <= S2 * (1 + 1e-4))))
    if len(bad):
        k = bad[0]
        raise CheckFailed(f"u = {u[k]:.6f}: r = {r[k]:.6f} moves it by {up[k]:+.6f}, r = {r[k] + 0.5:.6f} by "
                          f"{down[k]:+.6f}; a symmetric step moves by +d and -d with s1 = {S1:.6f} <= d <= s2 = "
                          f"{S2:.6f} ({len(bad)} of {len(u)} pairs wrong)")


@ASSIGNMENT.check("wrap", 15, "near 0 and 1, mlt_perturb wraps around [0, 1) (a circle), never leaves it",
                  "primary sample space is a torus: a step past 1 comes back at 0 and one below 0 at 1, so the "
                  "step's density stays the same at the edges; 1.0 itself is not in [0, 1)")
def _check_wrap(c):
    # Your own step, not Kelemen's (that is `perturb`'s): the step of r from u near an edge must be
    # the step of the same r from the middle (u = 1/2), modulo 1, and land in [0, 1).
    rng = c.rng(63)
    n = 2048
    low, high = rng.uniform(0, S2, n), rng.uniform(1 - S2, 1, n)
    u = np.concatenate([low, high, [0.0, 0.0, 1 - 2 ** -24]])
    r = np.concatenate([0.5 + 0.5 * rng.random(n), 0.5 * rng.random(n), [0.75, 0.999999, 0.0]])  # down, up
    got, middle = _perturb(c, u, r), _perturb(c, np.full(len(u), 0.5), r)
    step = middle.astype(np.float64) - 0.5
    if np.all(step == 0):
        raise CheckFailed("mlt_perturb does not move u (from u = 0.5), so nothing wraps")
    outside = np.flatnonzero(~((got >= 0) & (got < 1)))
    if len(outside):
        k = outside[0]
        raise CheckFailed(f"mlt_perturb(u={u[k]:.6f}, r={r[k]:.6f}) = {got[k]:.6f}, outside [0, 1) "
                          f"({len(outside)} of {len(u)} steps near the edges)")
    wrong = np.flatnonzero(~(_circular(got, u + step) <= _TOLERANCE))
    if len(wrong):
        k = wrong[0]
        raise CheckFailed(f"mlt_perturb(u={u[k]:.6f}, r={r[k]:.6f}) = {got[k]:.6f}: the same r moves u = 0.5 by "
                          f"{step[k]:+.6f}, which wraps to {(u[k] + step[k]) % 1.0:.6f} ({len(wrong)} of {len(u)} wrong)")


def _buffers(c, chains, current, dims):
    vectors = c.buffer(current.astype(np.float32).ravel())
    proposal = c.buffer(np.full(current.size, np.nan, np.float32))
    records = MLT_CHAIN.zeros(chains)
    records["dims_current"], records["large_step"] = dims, -1
    return vectors, proposal, c.buffer(records)


def _iteration(chains, seed, mode, large_step):
    it = MLT_ITERATION.zeros(1)[0]
    it["seed"], it["chains"], it["active"], it["large_step"], it["mode"] = seed, chains, chains, large_step, int(mode)
    it["iteration"] = 3
    return it


def _mutate(c, directory, it, current, dims):
    """mlt_mutate of cl/mlt_test.cl's build (the student's file or the toolkit's): proposal
    (dims, chains) and each chain's large_step flag."""
    chains = it["chains"]
    built = program.build(c.queue, "mlt_test.cl", _DEFINES, directory=directory)
    vectors, proposal, records = _buffers(c, chains, current, dims)
    program.launch(c.queue, program.kernel(built, "mlt_mutate"), chains, it, vectors, proposal, records)
    out = c.read(proposal, np.float32, current.size).reshape(current.shape)
    return out, c.read(records, MLT_CHAIN.dtype, chains)["large_step"]


@ASSIGNMENT.check("large_step", 15, "mlt_mutate: a large step with probability large_step (always at the start) "
                                    "marks every dimension fresh; a small step perturbs the dimensions the "
                                    "current state used and marks the others fresh",
                  "dimension 0 of the mutation's random numbers chooses the step; a large step is a new BDPT "
                  "sample (every dimension fresh), a small one touches only what the current path used", hidden=True)
def _check_large_step(c):
    rng = c.rng(64)
    chains, max_dims = 4096, mlt_toy.MAX_DIMS
    current = rng.random((max_dims, chains))   # dimension-major: MLT_CHAIN_MAJOR is 0 here
    dims = rng.integers(0, max_dims + 1, chains).astype(np.int32)
    for mode, p in ((MltMode.START, 0.3), (MltMode.MUTATE, 1.0), (MltMode.MUTATE, 0.3), (MltMode.MUTATE, 0.0)):
        it = _iteration(chains, c.seed(7), mode, p)
        got, large = _mutate(c, c.sources(), it, current, dims)
        _, expected_large = _mutate(c, c.reference_sources(), it, current, dims)
        where = f"{mode.name} with large_step {p}"
        wrong = np.flatnonzero(large != expected_large)
        if len(wrong):
            k = wrong[0]
            raise CheckFailed(f"{where}: chain {k} records large_step = {large[k]}, its random number chooses "
                              f"{expected_large[k]} ({len(wrong)} of {chains} chains)")
        used = np.where(expected_large != 0, 0, dims)
        fresh_expected = np.arange(max_dims)[:, None] >= used[None, :]
        fresh = got == _FRESH
        stored = np.isfinite(got) & (got != _FRESH)   # its value is `perturb`'s and `wrap`'s business
        bad = np.flatnonzero(~np.all(np.where(fresh_expected, fresh, stored), axis=0))
        if len(bad):
            k = bad[0]
            kind = "large" if expected_large[k] else f"small (the current state used {dims[k]} dimensions)"
            raise CheckFailed(f"{where}: chain {k}, a {kind} step, proposes {[round(float(x), 4) for x in got[:, k]]}; "
                              f"expected MLT_FRESH (-1) in the dimensions from {used[k]} on and perturbed values "
                              f"below ({len(bad)} of {chains} chains)")


@ASSIGNMENT.check("stationary", 15, "tutorial 05's chi-square test: 16,384 chains, 150 iterations (large_step 0.3) "
                                    "on its known target, final states distributed like f (p >= 0.001)",
                  "the chains sample f only if the proposal is symmetric and reaches everywhere: small steps "
                  "around the circle, large steps uniform")
def _check_stationary(c):
    # 150 iterations leave a total variation of <= 2e-4 to the target after the naive start
    # (tests/test_mlt.py): far below the statistic's spread.
    p = mlt_toy.chi2_p(mlt_toy.run_chains(c.queue, 16384, 150, seed=1, large_step=0.3, directory=c.sources()))
    if not p >= ALPHA:
        raise CheckFailed(f"the chains' final states are not distributed like the target: chi-square p = {p:.2e} "
                          f"(< {ALPHA})")


@ASSIGNMENT.check("small_steps", 10, "tutorial 05's invariance test: chains started in the target stay in it "
                                     "after 200 small steps (large_step 0, chi-square p >= 0.001)",
                  "a small step alone must keep f invariant: symmetric, wrapped at 0 and 1, and perturbing "
                  "only the dimensions the current state used (the others fresh)")
def _check_small_steps(c):
    start = mlt_toy.sample_target(16384, seed=2)
    moved = mlt_toy.run_chains(c.queue, 16384, 200, seed=3, large_step=0.0, initial=start, directory=c.sources())
    p = mlt_toy.chi2_p(moved)
    if not p >= ALPHA:
        raise CheckFailed(f"after 200 small steps from the target the chains have drifted: chi-square p = {p:.2e} "
                          f"(< {ALPHA})")
    if np.mean(_circular(moved[:, 0], start[:, 0]) > 0.02) < 0.5:
        raise CheckFailed("after 200 small steps fewer than half of the chains moved u0 by more than 0.02: "
                          "the small step hardly moves")


def _large_step_contributions(c, chains, seed, large_step):
    """One Metropolis iteration on the toy target (cl/mlt_test.cl) from states drawn from the
    target: the f of the proposals that were large steps."""
    built = program.build(c.queue, "mlt_test.cl", _DEFINES, directory=c.sources())
    max_dims = mlt_toy.MAX_DIMS
    current = np.random.default_rng(seed).random((max_dims, chains))
    current[:2] = mlt_toy.sample_target(chains, seed=seed + 1).T
    dims = np.where(current[0] < 0.5, 1, 2).astype(np.int32)
    vectors, proposal, records = _buffers(c, chains, current, dims)
    f, used = c.buffer(np.zeros(chains, np.float32)), c.buffer(np.zeros(chains, np.int32))
    it = _iteration(chains, seed, MltMode.MUTATE, large_step)
    program.launch(c.queue, program.kernel(built, "mlt_mutate"), chains, it, vectors, proposal, records)
    program.launch(c.queue, program.kernel(built, "mlt_test_target"), chains, it, proposal, f, used)
    large = c.read(records, MLT_CHAIN.dtype, chains)["large_step"]
    return c.read(f, np.float32, chains)[large == 1].astype(np.float64)


@ASSIGNMENT.check("normalisation", 10, "b, the mean f of the large steps (the on-the-fly normalisation), "
                                       "estimates the target's integral 9/8 within its standard error",
                  "a large step is a fresh uniform sample, so the mean of its f is an unbiased estimate of the "
                  "integral b; a large step that keeps anything of the current state is not")
def _check_normalisation(c):
    chains, p = 65536, 0.3
    f = _large_step_contributions(c, chains, seed=11, large_step=p)
    n = len(f)
    # The number of large steps is binomial(chains, p); the mean of n independent f's is normal
    # (central limit, n ~ 20k) with standard error std(f) / sqrt(n): both within Z_BOUND.
    if abs(n - chains * p) > Z_BOUND * np.sqrt(chains * p * (1 - p)) or n < 2:
        raise CheckFailed(f"{n} of {chains} proposals were large steps at large_step {p}: expected "
                          f"{chains * p:.0f} +- {np.sqrt(chains * p * (1 - p)):.0f}")
    b, se = f.mean(), f.std(ddof=1) / np.sqrt(n)
    if not abs(b - mlt_toy.TARGET_INTEGRAL) <= Z_BOUND * se:
        raise CheckFailed(f"b from {n} large steps is {b:.4f} +- {se:.4f}, the target's integral is "
                          f"{mlt_toy.TARGET_INTEGRAL:.4f} ({abs(b - mlt_toy.TARGET_INTEGRAL) / se:.1f} standard errors off)")


_IMAGE_SEEDS = 11   # independent MLT renders: the z-test wants >= 10 degrees of freedom (tests/test_mlt.py)


def _mlt(c):
    # No SIMD counters: the image is all this check reads, and counting reads the lanes back at
    # every step (twice the check's time, which must stay well inside the per-check limit)
    return c.technique(Mlt, chains=256, candidates=8, start="resample", count_simd=False)


@ASSIGNMENT.check("image", 10, "mlt with your mutation matches the cornell_box reference within statistical "
                               "error (11 independent renders, z-test at alpha 0.01)",
                  "the image is the chains' histogram times b: a mutation that is not symmetric, or large "
                  "steps that are not uniform, bias it")
def _check_image(c):
    scene, _ = c.scene("cornell_box")
    tech = _mlt(c)
    # Fixed seeds even for hidden inputs: a z-test at alpha 0.01 fails one right solution in a
    # hundred on seeds nobody has checked; these were. The error is the spread of the renders.
    images = np.array([tech.render(8, 8, 64, seed=100 + s).image() for s in range(_IMAGE_SEEDS)])
    if not np.isfinite(images).all():
        raise CheckFailed("the image has non-finite pixels")
    ref, ref_err = reference_at(scene, 8, 8)
    mean, stderr = images.mean(0), images.std(0, ddof=1) / np.sqrt(_IMAGE_SEEDS)
    rel = relative_mean_error(mean, ref)
    if np.any(rel > 0.03):
        raise CheckFailed(f"the image mean is off the reference by {np.round(100 * rel, 1).tolist()}% (R, G, B)")
    test = z_test(mean, stderr, ref, ref_err, alpha=0.01, dof=_IMAGE_SEEDS - 1)
    if not test.passed:
        raise CheckFailed(f"the image does not match the reference within its statistical error: {test}")
