"""The Metropolis kernels of cl/mlt.h (mutate, accept) on a known two-dimensional target
(cl/mlt_test.cl) instead of light paths: many independent chains, whose states after enough
iterations must be distributed like the target, f normalized. tests/test_mlt.py checks this
with a chi-square test; tutorials/05_metropolis.ipynb plots it.
"""
import numpy as np
import pyopencl as cl

from toolkit.core.stats import chi2_sf, pearson
from toolkit.opencl import program
from toolkit.core.layout import MLT_CHAIN, MLT_ITERATION, MltMode
from toolkit.techniques.mlt import SMALL_STEP, step_defines

TARGET_INTEGRAL = 9.0 / 8.0
MAX_DIMS = 4     # the target reads 1 or 2 of them


def target(u0, u1):
    """The target of cl/mlt_test.cl, on the host (for plots and expected counts)."""
    u0, u1 = np.asarray(u0, np.float64), np.asarray(u1, np.float64)
    return np.where(u0 < 0.5, 0.5 + u0, 6.0 * u0 * u1 ** 2)


def bin_probabilities(bins):
    """Probability of each of bins x bins cells of [0, 1)^2 (u0 along axis 0) under f / (9/8):
    the integrals of the two pieces over a cell, exactly."""
    e = np.linspace(0.0, 1.0, bins + 1)
    lo, hi = e[:-1], e[1:]
    # u0 < 1/2: (1/2 + u0), independent of u1; u0 >= 1/2: 2 u0 * 3 u1^2 (bin edges split at 1/2 when bins is even)
    low_piece = np.where(hi <= 0.5, 0.5 * (hi - lo) + 0.5 * (hi ** 2 - lo ** 2), 0.0)
    high_piece = np.where(lo >= 0.5, hi ** 2 - lo ** 2, 0.0)
    p = low_piece[:, None] * (hi - lo)[None, :] + high_piece[:, None] * (hi ** 3 - lo ** 3)[None, :]
    return p / TARGET_INTEGRAL


def chi2_p(states, bins=8):
    """The p-value of Pearson's chi-square test of chain states (chains, 2) against f / (9/8) on
    bins x bins cells (cells below 5 expected pooled): tutorial 05's test, and the grader's
    (toolkit/grading/checks/mlt_mutation.py)."""
    observed, _, _ = np.histogram2d(states[:, 0], states[:, 1], bins=bins, range=[[0, 1], [0, 1]])
    statistic, dof, *_ = pearson(observed, bin_probabilities(bins) * len(states))
    return chi2_sf(statistic, dof)


def sample_target(n, seed=0):
    """n exact samples of f / (9/8), by rejection on the host (f <= 6)."""
    rng = np.random.default_rng(seed)
    out = np.empty((0, 2))
    while len(out) < n:
        u = rng.random((2 * n, 2))
        keep = rng.random(2 * n) * 6.0 < target(u[:, 0], u[:, 1])
        out = np.concatenate([out, u[keep]])
    return out[:n]


def run_chains(queue, chains, iterations, seed=0, large_step=0.3, history=False, initial=None, directory=None):
    """Run `chains` independent chains for `iterations` Metropolis steps after a naive start
    (one large step), or from the states `initial` (chains, 2). Returns the final (u0, u1) of
    every chain, shape (chains, 2), and with `history` also the states of chain 0 at every
    iteration (iterations + 1, 2) and its acceptance rate. `directory`: where the build finds
    cl/mlt_mutation.h (the grader passes a submission's: toolkit/grading/checks/mlt_mutation.py)."""
    built = program.build(queue, "mlt_test.cl", {"MLT_MAX_DIMS": MAX_DIMS, **step_defines(SMALL_STEP)},
                          directory=directory)
    ctx, n = queue.context, program.padded(chains)
    current = cl.Buffer(ctx, cl.mem_flags.READ_WRITE, 4 * n * MAX_DIMS)
    proposal = cl.Buffer(ctx, cl.mem_flags.READ_WRITE, 4 * n * MAX_DIMS)
    records = cl.Buffer(ctx, cl.mem_flags.READ_WRITE, MLT_CHAIN.dtype.itemsize * n)
    cl.enqueue_fill_buffer(queue, records, np.int32(0), 0, MLT_CHAIN.dtype.itemsize * n)
    f = cl.Buffer(ctx, cl.mem_flags.READ_WRITE, 4 * n)
    dims = cl.Buffer(ctx, cl.mem_flags.READ_WRITE, 4 * n)
    it = MLT_ITERATION.zeros(1)[0]
    it["seed"], it["chains"], it["active"], it["large_step"] = seed, chains, chains, large_step
    trace, accepted = [], 0
    if initial is not None:
        vectors = np.random.default_rng(seed).random((MAX_DIMS, chains)).astype(np.float32)
        vectors[:2] = np.asarray(initial, np.float32).T
        cl.enqueue_copy(queue, current, vectors)
        rec = MLT_CHAIN.zeros(chains)
        rec["f_current"] = target(vectors[0], vectors[1])
        rec["dims_current"] = np.where(vectors[0] < 0.5, 1, 2)
        cl.enqueue_copy(queue, records, rec)
    for k in range(iterations + 1):
        it["iteration"], it["mode"] = k, int(MltMode.START if k == 0 and initial is None else MltMode.MUTATE)
        for name, args in (("mlt_mutate", (current, proposal, records)), ("mlt_test_target", (proposal, f, dims)),
                           ("mlt_accept", (current, proposal, records, f, dims))):
            program.launch(queue, program.kernel(built, name), chains, it, *args)
        if history:
            state = np.empty(2, np.float32)
            cl.enqueue_copy(queue, state[:1], current)
            cl.enqueue_copy(queue, state[1:], current, src_offset=4 * chains)
            trace.append(state)
            if k or initial is not None:
                rec = MLT_CHAIN.zeros(1)
                cl.enqueue_copy(queue, rec, records)
                accepted += int(rec["accepted"][0])
    vectors = np.empty(MAX_DIMS * chains, np.float32)
    cl.enqueue_copy(queue, vectors, current)
    final = vectors.reshape(MAX_DIMS, chains)[:2].T.copy()
    # A state is the values of the dimensions it uses; mlt_accept stores only those. The target
    # of a state that uses u0 alone is uniform in u1 (f does not read it), as the next small step
    # would draw it: so draw it here.
    rec = MLT_CHAIN.zeros(chains)
    cl.enqueue_copy(queue, rec, records)
    unused = rec["dims_current"] < 2
    final[unused, 1] = np.random.default_rng(seed + 1).random(int(unused.sum()))
    if history:
        return final, np.array(trace), accepted / max(iterations, 1)
    return final
