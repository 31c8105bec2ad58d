"""Assignment 3, MIS weights for BDPT (tutorials/assignments/mis/): the checks of a student's
cl/mis.h, on real paths of the toolkit's BDPT (cl/bdpt_test.cl computes every split's weight)."""
from pathlib import Path

import numpy as np
import pyopencl as cl

from toolkit.core.layout import BDPT_VERTEX
from toolkit.grading.assignment import Assignment, CheckFailed
from toolkit.measure.reference import reference_at, relative_mean_error, z_test
from toolkit.opencl import program
from toolkit.techniques import BdptParallelConnect

ASSIGNMENT = Assignment("mis", "MIS weights for BDPT: balance and power heuristics", "mis.h", "mis_stub.cl",
                        headers=("common.h", "bdpt_vertex.h"))


@ASSIGNMENT.builds
def build(c):
    """Everything the checks build."""
    for scene_name in ("cornell_box", "cornell_spheres"):
        _, ds = c.scene(scene_name)
        for student in (True, False):
            tech = c.technique(BdptParallelConnect, student, scene=scene_name)
            for power in (False, True):
                defines = dict(ds.features(), MAX_VERTICES=tech.max_vertices, MIS_POWER=power)
                program.build(c.queue.context, "bdpt_test.cl", defines, directory=c.sources() if student else None)


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


@ASSIGNMENT.check("balance_sum", 25, "balance heuristic: the weights of every split of real paths sum to one")
def _check_balance_sum(c):
    for scene_name, tech, paths in _mis_cases(c):
        problem = _sum_problem(scene_name, _split_weights(c, tech, scene_name, paths))
        if problem:
            raise CheckFailed(problem)


@ASSIGNMENT.check("balance", 15, "balance heuristic: each weight is p_s / sum_i p_i")
def _check_balance(c):
    for scene_name, tech, paths in _mis_cases(c):
        problem = _match_problem(scene_name, _split_weights(c, tech, scene_name, paths),
                                 _split_weights(c, tech, scene_name, paths, student=False), "balance heuristic")
        if problem:
            raise CheckFailed(problem)


@ASSIGNMENT.check("power", 25, "power heuristic (-DMIS_POWER=1): each weight is p_s^2 / sum_i p_i^2, sums to one")
def _check_power(c):
    for scene_name, tech, paths in _mis_cases(c):
        weights = _split_weights(c, tech, scene_name, paths, power=True)
        balance = _split_weights(c, tech, scene_name, paths, student=False)
        expected = [b * b / np.sum(b * b) for b in balance]
        problem = _sum_problem(scene_name, weights, "power") or _match_problem(
            scene_name, weights, expected, "power heuristic")
        if problem:
            raise CheckFailed(problem)


@ASSIGNMENT.check("image", 35, "bdpt_parallel_connect with your weights matches the reference within statistical error")
def _check_mis_image(c):
    scene, _ = c.scene("cornell_box")
    tech = c.technique(BdptParallelConnect, target_batch=1 << 10)   # 16 passes: the error from passes
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
