"""Assignment 4, MIS weights for BDPT (tutorials/assignments/mis/): the checks of a student's
cl/mis.h, on real paths of the toolkit's BDPT (cl/bdpt_test.cl computes every split's weight)."""
from pathlib import Path

import numpy as np
import pyopencl as cl

from toolkit.core.layout import BDPT_VERTEX
from toolkit.grading.assignment import Assignment, CheckFailed
from toolkit.measure.reference import reference_at, relative_mean_error, z_test
from toolkit.opencl import program
from toolkit.techniques import BdptNaiveConnect, BdptParallelConnect

# The points: weights that sum to one but are not the heuristic asked for (uniform ones, say)
# pass balance_sum and image, and earn at most a third (30).
ASSIGNMENT = Assignment("mis", "MIS weights for BDPT: balance and power heuristics", "mis.h", "mis_stub.cl",
                        ("mis_checks.cl",), headers=("common.h", "bdpt_vertex.h"))


@ASSIGNMENT.builds
def build(c):
    """Everything the checks that run build: the image renders with the student's naive-connect BDPT (on the
    Cornell box); the weights of real paths come from bdpt_test.cl, on paths of the toolkit's BDPT."""
    if c.runs("image"):
        c.technique(BdptNaiveConnect, scene="cornell_box")
    for scene_name in ("cornell_box", "cornell_spheres"):
        _, ds = c.scene(scene_name)
        tech = c.technique(BdptParallelConnect, student=False, scene=scene_name)
        for student in (True, False):
            for power in (False, True):
                defines = dict(ds.features(), MAX_VERTICES=tech.max_vertices, MIS_POWER=power)
                program.build(c.queue.context, "bdpt_test.cl", defines, directory=c.sources() if student else None)
    for power in (False, True):
        c.build("mis_checks.cl", {"MIS_POWER": power})


_PATHS = 100   # real paths per scene


def _real_paths(c, scene_name):
    """Eye paths of the toolkit's own BDPT that end on the front of a light, light -> eye order."""
    tech = c.technique(BdptParallelConnect, student=False, scene=scene_name)
    tech.render(64, 64, 1, seed=0)
    return tech, tech.eye_paths_to_lights(_PATHS)


def _split_weights(c, tech, scene_name, paths, student=True, power=False):
    """The MIS weight of every split s of each path (cl/bdpt_test.cl with the submission's mis.h)."""
    _, ds = c.scene(scene_name)
    # The device scene's features: they say which BVH layout (binary or wide) the kernel traverses.
    defines = dict(ds.features(), MAX_VERTICES=tech.max_vertices, MIS_POWER=power)
    built = program.build(c.queue.context, "bdpt_test.cl", defines, directory=c.sources() if student else None)
    kernel = program.kernel(built, "bdpt_test_mis_splits")
    camera = ds.camera(64, 64)
    out = []
    for path in paths:
        n = len(path)
        scratch = [cl.Buffer(c.queue.context, cl.mem_flags.READ_WRITE, BDPT_VERTEX.dtype.itemsize * n * tech.max_vertices)
                   for _ in range(2)]
        weights = c.buffer(np.full(n, np.nan, np.float32))
        program.launch(c.queue, kernel, n, *ds.args(), camera, np.int32(n), c.buffer(path), *scratch, weights)
        out.append(c.read(weights, np.float32, n))
    return out


def _mis_cases(c):
    """(scene name, technique, real paths) of both scenes; the paths are found once per grading
    (the checks' subprocesses share the grading folder) and kept there."""
    for scene_name in ("cornell_box", "cornell_spheres"):
        saved = Path(c.folder) / f"paths_{scene_name}.npz"
        if saved.is_file():
            with np.load(saved) as data:
                paths = [data[f"p{i}"] for i in range(len(data.files))]
            tech = c.technique(BdptParallelConnect, student=False, scene=scene_name)
        else:
            tech, paths = _real_paths(c, scene_name)
            np.savez(saved, **{f"p{i}": p for i, p in enumerate(paths)})
        if len(paths) < 20:
            raise RuntimeError(f"too few paths reached a light in {scene_name}")
        yield scene_name, tech, paths


def _sum_problem(scene_name, weights, what="balance"):
    for w in weights:
        total = float(np.sum(w))
        if not np.all(np.isfinite(w)) or np.any(w < 0) or np.any(w > 1 + 1e-5) or abs(total - 1) > 1e-4:
            return (f"{scene_name}: the {what} weights of the {len(w)} strategies of a {len(w)}-vertex path sum to "
                    f"{total:.5f}, not 1: {np.round(w.astype(float), 3).tolist()}")
    return None


def _match_problem(scene_name, weights, expected, what):
    for w, e in zip(weights, expected):
        wrong = np.flatnonzero(~(np.abs(w - e) <= 2e-4))
        if len(wrong):
            s = wrong[0]
            return (f"{scene_name}: strategy s = {s} of a {len(w)}-vertex path has weight {w[s]:.5f}, the {what} "
                    f"gives {e[s]:.5f}")
    return None


@ASSIGNMENT.check("balance_sum", 10, "balance heuristic: the weights of every split of real paths sum to one",
                  "the strategies that can make a path share it: their weights sum to one, and a strategy that "
                  "cannot (a connection at a delta vertex) is left out of every sum")
def _check_balance_sum(c):
    for scene_name, tech, paths in _mis_cases(c):
        problem = _sum_problem(scene_name, _split_weights(c, tech, scene_name, paths))
        if problem:
            raise CheckFailed(problem)


def _known_cases(rng, n=64):
    """Cases of known densities (log-uniform over two decades, no delta vertex): strategy (s, t),
    the subpaths' pdf_fwd and pdf_rev, the four recomputed densities, and each case's balance
    and power weights computed here from the formula of the handout."""
    st = np.stack([rng.integers(0, 5, n), rng.integers(1, 6, n)], axis=1).astype(np.int32)
    density = lambda *shape: np.exp(rng.uniform(np.log(0.1), np.log(10.0), shape)).astype(np.float32)
    eye_fwd, eye_rev, light_fwd, light_rev, pdfs = (density(n, _STRIDE), density(n, _STRIDE), density(n, _STRIDE),
                                                    density(n, _STRIDE), density(n, 4))
    ratios = []
    for k, (s, t) in enumerate(st):
        terms, r = [], 1.0
        for i in range(t - 1, 0, -1):
            r *= (pdfs[k, 0] if i == t - 1 else pdfs[k, 1] if i == t - 2 else eye_rev[k, i + 1]) / eye_fwd[k, i]
            terms.append(r)
        r = 1.0
        for i in range(s - 1, -1, -1):
            r *= (pdfs[k, 2] if i == s - 1 else pdfs[k, 3] if i == s - 2 else light_rev[k, i + 1]) / light_fwd[k, i]
            terms.append(r)
        ratios.append(np.array(terms, np.float64))
    expected = {power: np.array([1 / (1 + np.sum(r ** (2 if power else 1))) for r in ratios]) for power in (0, 1)}
    return st, (eye_fwd, eye_rev, light_fwd, light_rev), pdfs, expected


_STRIDE = 8   # vertices per subpath in the known cases


def _known_weights(c, st, densities, pdfs, power):
    built = c.build("mis_checks.cl", {"MIS_POWER": power})
    n = len(st)
    subpaths = []
    for fwd, rev in (densities[:2], densities[2:]):
        v = BDPT_VERTEX.zeros(n * _STRIDE)
        v["pdf_fwd"], v["pdf_rev"] = fwd.ravel(), rev.ravel()
        subpaths.append(c.buffer(v))
    weights = c.buffer(np.full(n, np.nan, np.float32))
    program.launch(c.queue, program.kernel(built, "grade_mis_known"), n, *subpaths, c.buffer(st), c.buffer(pdfs),
                   np.int32(_STRIDE), np.int32(n), weights)
    return c.read(weights, np.float32, n)


@ASSIGNMENT.check("heuristic", 20, "on known densities, the weights are the balance heuristic and (MIS_POWER=1) the "
                                   "power heuristic, not another rule", "MIS weights a strategy by how likely it is "
                  "to make the path: w_s = p_s^b / sum_i p_i^b from the density ratios, not by counting strategies")
def _check_heuristic(c):
    st, densities, pdfs, expected = _known_cases(c.rng(11))
    for power, name in ((0, "balance"), (1, "power")):
        got = _known_weights(c, st, densities, pdfs, power)
        wrong = np.flatnonzero(~(np.abs(got - expected[power]) <= 1e-4 + 1e-3 * expected[power]))
        if len(wrong):
            k = wrong[0]
            s, t = st[k]
            uniform = np.allclose(got, 1.0 / (st[:, 0] + st[:, 1]), atol=1e-4)
            raise CheckFailed(f"{name} heuristic, strategy (s, t) = ({s}, {t}) of known densities: weight "
                              f"{got[k]:.5f}, the {name} heuristic gives {expected[power][k]:.5f} ({len(wrong)} of "
                              f"{len(st)} cases wrong" + ("; your weights are uniform, 1 / (s + t)" if uniform else "")
                              + ")")


@ASSIGNMENT.check("balance", 20, "balance heuristic: each weight is p_s / sum_i p_i",
                  "walk each subpath backwards from the connection, multiplying one density ratio per vertex; "
                  "the last two vertices of each side use the recomputed densities")
def _check_balance(c):
    for scene_name, tech, paths in _mis_cases(c):
        problem = _match_problem(scene_name, _split_weights(c, tech, scene_name, paths),
                                 _split_weights(c, tech, scene_name, paths, student=False), "balance heuristic")
        if problem:
            raise CheckFailed(problem)


@ASSIGNMENT.check("power", 30, "power heuristic (-DMIS_POWER=1): each weight is p_s^2 / sum_i p_i^2, sums to one",
                  "the power heuristic squares each strategy's density ratio before it is summed, the evaluated "
                  "strategy's own term (1) included")
def _check_power(c):
    for scene_name, tech, paths in _mis_cases(c):
        weights = _split_weights(c, tech, scene_name, paths, power=True)
        balance = _split_weights(c, tech, scene_name, paths, student=False)
        expected = [b * b / np.sum(b * b) for b in balance]
        problem = _sum_problem(scene_name, weights, "power") or _match_problem(
            scene_name, weights, expected, "power heuristic")
        if problem:
            raise CheckFailed(problem)


@ASSIGNMENT.check("image", 20, "bdpt_naive_connect with your weights matches the reference within statistical "
                               "error", "any weights that sum to one over the strategies that can make each path "
                  "keep the image unbiased; a bias means a strategy counted twice or left out")
def _check_mis_image(c):
    scene, _ = c.scene("cornell_box")
    # The naive connect: it uses no other assignment's file (bdpt_parallel_connect.cl is
    # parallel_connect's, a stub in the course's student edition). 16 passes: the error from passes.
    tech = c.technique(BdptNaiveConnect, target_batch=1 << 10)
    # A fixed seed even for hidden inputs: a z-test at alpha 0.01 fails one right solution in a
    # hundred on seeds nobody has checked; this one was.
    film = tech.render(8, 8, 256, seed=5)
    image, stderr = film.image(), film.stderr()
    ref, ref_err = reference_at(scene, 8, 8)
    if not np.isfinite(image).all():
        raise CheckFailed("the image has non-finite pixels")
    rel = relative_mean_error(image, ref)
    if np.any(rel > 0.03):
        raise CheckFailed(f"the image mean is off the reference by {np.round(100 * rel, 1).tolist()}% (R, G, B)")
    test = z_test(image, stderr, ref, ref_err, alpha=0.01, dof=film.degrees_of_freedom)
    if not test.passed:
        raise CheckFailed(f"the image does not match the reference within its statistical error: {test}")
