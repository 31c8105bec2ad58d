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
from toolkit.techniques.bdpt_evaluator import walk_defines

# The points. The assignment asks for two heuristics, the balance one (MIS_POWER 0) and the power
# one (MIS_POWER 1, beta = 2); a file that computes another rule in either build (uniform weights,
# the balance heuristic in the power build, another exponent, the maximum heuristic) loses
# `heuristic` and `weights` (70) and keeps at most `sum_to_one` and `image` (30): at most a third.
ASSIGNMENT = Assignment("mis", "MIS weights for BDPT: balance and power heuristics", "mis.h", "mis_stub.cl",
                        ("mis_checks.cl",), headers=("common.h", "bdpt_vertex.h"))


@ASSIGNMENT.builds
def build(c):
    """Everything the checks that run build: the image renders with the student's naive-connect BDPT (on the
    Cornell box); the weights of real paths come from bdpt_test.cl, on paths of the toolkit's BDPT."""
    if c.runs("image"):
        c.technique(BdptNaiveConnect, scene="cornell_box")
    for student in (True, False):
        for power in (False, True):
            _build_bdpt_test(c, power, student)
    for power in (False, True):
        c.build("mis_checks.cl", {"MIS_POWER": power})
    # The real paths too, once (_mis_cases keeps them in the grading folder): found here, within the
    # build step's limit, the first check that needs them does not pay for it out of its own time limit
    # (sum_to_one, which runs both heuristics, was stopped at 10 s once in a whole-suite run).
    if c.runs("sum_to_one", "weights"):
        for _ in _mis_cases(c):
            pass


_PATHS = 100   # real paths per scene


def _real_paths(c, scene_name):
    """Eye paths of the toolkit's own BDPT that end on the front of a light, light -> eye order."""
    tech = c.technique(BdptParallelConnect, student=False, scene=scene_name)
    tech.render(64, 64, 1, seed=0)
    return tech, tech.eye_paths_to_lights(_PATHS)


_SCENES = ("cornell_box", "cornell_spheres")   # the scenes whose real paths the weights are checked on


def _bdpt_test_defines(c, power):
    """bdpt_test.cl's defines for the paths of both scenes: one build, not one per scene (each
    build of a student's file costs seconds of the grading's limit). A material either scene has
    is compiled in (HAS_*): a scene without it never reaches its code, so its paths come out as
    from its own build (tests/test_specialization.py holds the general kernel to the specialized
    one). Every other define (the BVH layout, the depth limits, the vertex count) must agree."""
    merged = {}
    for scene_name in _SCENES:
        scene, ds = c.scene(scene_name)
        # The technique's own rule for its subpaths' length, without building a technique for it.
        max_vertices, _ = walk_defines(scene, BdptParallelConnect.max_vertices, coalesced_scatter=True)
        for key, value in dict(ds.features(), MAX_VERTICES=max_vertices).items():
            if key.startswith("HAS_"):
                merged[key] = merged.get(key, False) or value
            elif merged.setdefault(key, value) != value:
                raise RuntimeError(f"bdpt_test.cl cannot be built once for {_SCENES}: their {key} differs "
                                   f"({merged[key]} and {value})")
    return dict(merged, MIS_POWER=power)


def _build_bdpt_test(c, power, student=True):
    return program.build(c.queue, "bdpt_test.cl", _bdpt_test_defines(c, power),
                         directory=c.sources() if student else c.reference_sources())


def _split_weights(c, tech, scene_name, paths, student=True, power=False):
    """The MIS weight of every split s of each path (cl/bdpt_test.cl with the submission's mis.h)."""
    _, ds = c.scene(scene_name)
    kernel = program.kernel(_build_bdpt_test(c, power, student), "bdpt_test_mis_splits")
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
    for scene_name in _SCENES:
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


_HEURISTICS = ((False, "balance"), (True, "power"))   # (MIS_POWER, the heuristic that build asks for)


def _sum_problem(scene_name, weights, what):
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


@ASSIGNMENT.check("sum_to_one", 10, "on real paths, the weights of every split sum to one, with both heuristics",
                  "the strategies that can make a path share it: their weights sum to one, and a strategy that "
                  "cannot (a connection at a delta vertex) is left out of every sum", hidden=True)
def _check_sum_to_one(c):
    for scene_name, tech, paths in _mis_cases(c):
        for power, name in _HEURISTICS:
            problem = _sum_problem(scene_name, _split_weights(c, tech, scene_name, paths, power=power), name)
            if problem:
                raise CheckFailed(problem)


def _known_cases(rng, n=64):
    """Cases of known densities (log-uniform over two decades, no delta vertex): strategy (s, t),
    the subpaths' pdf_fwd and pdf_rev, the four recomputed densities, and each case's ratios
    r_i = p_i / p_s of the other strategies, computed here from the recurrence of the handout."""
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
    return st, (eye_fwd, eye_rev, light_fwd, light_rev), pdfs, ratios


_STRIDE = 8   # vertices per subpath in the known cases


def _power_rule(ratios, beta):
    """w_s = p_s^beta / sum_i p_i^beta = 1 / (1 + sum r_i^beta): beta 1 is the balance heuristic,
    2 the power heuristic asked for, 0 uniform weights (1 / the number of strategies)."""
    return np.array([1 / (1 + np.sum(r ** beta)) for r in ratios])


def _other_rules(ratios):
    """The rules a file may compute instead of the heuristic asked for, by name: the power rule of other
    exponents and its limit, the maximum heuristic (weight 1 for the likeliest strategy, 0 for the others)."""
    named = {0: "uniform weights, 1 / (s + t)", 1: "the balance heuristic (beta = 1)"}
    rules = {named.get(beta, f"the power heuristic with beta = {beta}"): _power_rule(ratios, beta)
             for beta in (0, 0.5, 1, 2, 3, 4)}
    rules["the maximum heuristic (1 for the likeliest strategy, 0 for the others)"] = np.array(
        [1.0 if np.all(r <= 1) else 0.0 for r in ratios])
    return rules


def _close(got, expected):
    return np.abs(got - expected) <= 1e-4 + 1e-3 * expected


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
                  "to make the path: w_s = p_s^b / sum_i p_i^b from the density ratios, with b = 1 (balance) and "
                  "b = 2 (power), not by counting strategies nor by keeping only the likeliest")
def _check_heuristic(c):
    st, densities, pdfs, ratios = _known_cases(c.rng(11))
    for (power, name), beta in zip(_HEURISTICS, (1, 2)):
        got = _known_weights(c, st, densities, pdfs, power)
        expected = _power_rule(ratios, beta)
        wrong = np.flatnonzero(~_close(got, expected))
        if len(wrong):
            k = wrong[0]
            s, t = st[k]
            rule = next((rule for rule, w in _other_rules(ratios).items() if np.all(_close(got, w))), None)
            raise CheckFailed(f"{name} heuristic (MIS_POWER={int(power)}), strategy (s, t) = ({s}, {t}) of known "
                              f"densities: weight {got[k]:.5f}, the {name} heuristic gives {expected[k]:.5f} "
                              f"({len(wrong)} of {len(st)} cases wrong" +
                              (f"; your weights follow another rule: {rule}" if rule else "") + ")")


@ASSIGNMENT.check("weights", 50, "on real paths, each weight is the balance heuristic's, p_s / sum_i p_i, and "
                                 "(MIS_POWER=1) the power heuristic's, p_s^2 / sum_i p_i^2",
                  "walk each subpath backwards from the connection, multiplying one density ratio per vertex (the "
                  "last two of each side use the recomputed densities), leave the strategies at delta vertices out "
                  "of the sum, and add each ratio as the heuristic asked for weighs it: r for balance, r^2 for power",
                  hidden=True)
def _check_weights(c):
    for scene_name, tech, paths in _mis_cases(c):
        balance = _split_weights(c, tech, scene_name, paths, student=False)
        # The power weights from the toolkit's balance ones: p_i is proportional to w_i.
        expected = {False: balance, True: [b * b / np.sum(b * b) for b in balance]}
        for power, name in _HEURISTICS:
            problem = _match_problem(f"{name} heuristic (MIS_POWER={int(power)}), {scene_name}",
                                     _split_weights(c, tech, scene_name, paths, power=power), expected[power],
                                     f"{name} heuristic")
            if problem:
                raise CheckFailed(problem)


@ASSIGNMENT.check("image", 20, "bdpt_naive_connect with your weights matches the reference within statistical "
                               "error", "any weights that sum to one over the strategies that can make each path "
                  "keep the image unbiased; a bias means a strategy counted twice or left out, or a share "
                  "given to a strategy that cannot make the path (its density for it is 0)")
def _check_mis_image(c):
    scene, _ = c.scene("cornell_box")
    # The naive connect: it uses no other assignment's file (bdpt_parallel_connect.cl is
    # parallel_connect's, a stub in the course's student edition). 16 passes of 16 samples per
    # pixel: the error from passes, on every device (a GPU's larger pool no longer makes it one pass).
    tech = c.technique(BdptNaiveConnect, pass_spp=16)
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
