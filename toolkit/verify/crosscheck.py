"""Cross-check of our BVH traversal (cl/bvh.h through cl/raycast.cl) against Embree.

Both intersectors answer the same float32 question: the scene's triangles in the device's
rebased coordinates and the same float32 rays. They use different triangle tests and
different rounding, so they may legitimately disagree where the answer is decided by
rounding: a ray through (or within float noise of) an edge shared by two triangles, or two
surfaces at the same distance. Such disagreements are "excused"; any other disagreement is
"unexplained" and means a traversal bug.

Excuse rule for a closest-hit disagreement (different prim, or hit against miss): the hit that
either intersector reports lies within EDGE_BARYCENTRIC of its triangle's edge
(min(u, v, 1 - u - v) < 1e-4), or both hit at distances equal to TIE_RELATIVE (a tie between
coplanar or edge-sharing triangles). An any-hit (segment) disagreement is excused when, for
the same ray, either intersector's closest hit on the segment is near an edge, or lies at the
segment's end (within TIE_RELATIVE of tmax), or the closest-hit disagreement is excused.

Two refinements of the figures (the rule above is unchanged):
- `ties_verified`: excused ties that float64 arithmetic proves to be genuine: the ray hits both
  reported triangles, inside, at the same distance (coplanar overlapping triangles, e.g. a
  box's bottom face lying on the floor). Both answers are right; `excused_rounding` is the
  count of excused rays without them, those decided by rounding alone.
- Distance error: `max_rel_t_error` is |t_device - t_embree| / t over rays whose prims agree,
  and `rel_t_error_above_tie` counts those rays above TIE_RELATIVE. That ratio is not what
  float32 can promise: the distance to a plane, t = n.(v0 - o) / n.d, is perturbed by the
  rounding of coordinates of size S (eps S) and of the direction (eps t), both divided by
  |cos| = |n.d|. A short hit (t << S) or a grazing one (|cos| << 1) has a relative error far
  above eps even when both intersectors are right. `max_t_error_conditioned` removes that
  condition number: |t_device - t_embree| |cos| / max(t, |origin|_inf, |hit point|_inf), in
  units of the coordinates' size; it should be a modest multiple of float32 eps (1.2e-7).
"""
import time
from pathlib import Path

import numpy as np

from toolkit.opencl.device import get_queue
from toolkit.opencl.device_scene import DeviceScene
from toolkit.peers.embree import EmbreeIntersector, camera_rays, random_rays
from toolkit.opencl.raycast import DeviceRaycaster
from toolkit.core.scene import Scene, load_scene
from toolkit.core.validate import camera_size

EDGE_BARYCENTRIC = 1e-4
TIE_RELATIVE = 1e-5


def edge_distance(u, v):
    """min(u, v, 1 - u - v): barycentric distance of a hit to its triangle's nearest edge."""
    u = np.asarray(u, np.float64)
    v = np.asarray(v, np.float64)
    return np.minimum(np.minimum(u, v), 1.0 - u - v)


def _moller_trumbore64(o, d, tri):
    """Float64 ray/triangle test of rays (K, 3) against triangles (K, 3, 3): (t, u, v)."""
    o, d, tri = (np.asarray(a, np.float64) for a in (o, d, tri))
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    pv = np.cross(d, e2)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / np.einsum("ij,ij->i", e1, pv)
        tv = o - tri[:, 0]
        u = np.einsum("ij,ij->i", tv, pv) * inv
        qv = np.cross(tv, e1)
        v = np.einsum("ij,ij->i", d, qv) * inv
        t = np.einsum("ij,ij->i", e2, qv) * inv
    return t, u, v


def verified_ties(origins, dirs, prim_a, prim_b, triangles):
    """Per ray: whether, in float64 on the same float32 data, the ray hits both triangles
    (inside, barycentrics >= 0) at distances equal to TIE_RELATIVE: both answers are then
    correct closest hits (coplanar overlapping triangles), not a rounding accident."""
    if len(prim_a) == 0:
        return np.zeros(0, bool)
    ta, ua, va = _moller_trumbore64(origins, dirs, triangles[prim_a])
    tb, ub, vb = _moller_trumbore64(origins, dirs, triangles[prim_b])
    with np.errstate(invalid="ignore"):
        inside = (edge_distance(ua, va) >= 0) & (edge_distance(ub, vb) >= 0) & (ta > 0) & (tb > 0)
        return inside & (np.abs(ta - tb) <= TIE_RELATIVE * np.maximum(ta, tb))


def _excused_closest(dev, emb):
    """Per ray: whether a closest-hit disagreement is excused (edge or tie), see module doc."""
    td, pd, ud, vd = dev
    te, pe, ue, ve = emb
    hd, he = pd >= 0, pe >= 0
    near_d = hd & (edge_distance(ud, vd) < EDGE_BARYCENTRIC)
    near_e = he & (edge_distance(ue, ve) < EDGE_BARYCENTRIC)
    with np.errstate(invalid="ignore"):
        tie = hd & he & (np.abs(td.astype(np.float64) - te) <= TIE_RELATIVE * np.maximum(td, te))
    return near_d | near_e | tie, near_d | near_e, tie


def compare_with_embree(scene, n_random=100_000, seed=0, resolution=None, queue=None,
                        max_examples=5, bvh="wide"):
    """Agreement figures of device traversal and Embree on camera and random rays.

    `scene`: a Scene or a scene folder. `resolution`: None (the scene's camera), an int
    (square) or (width, height). `bvh`: "wide" or "binary", the traversal checked. Returns a dict; `unexplained` (closest hit) and
    `any_unexplained` (segments) must be 0."""
    if not isinstance(scene, Scene):
        scene = load_scene(Path(scene))
    width, height = _resolution_of(scene, resolution)
    queue = queue or get_queue()
    start = time.perf_counter()
    device_scene = DeviceScene(queue, scene, bvh=bvh)
    device = DeviceRaycaster(queue, device_scene)
    embree = EmbreeIntersector(scene, center=device_scene.center)
    assert np.array_equal(embree.center, device_scene.center)

    rng = np.random.default_rng(seed)
    co, cd = camera_rays(device_scene, width, height)
    ro, rd = random_rays(device_scene, n_random, rng)
    origins, dirs = np.concatenate([co, ro]), np.concatenate([cd, rd])
    dev = device.closest(origins, dirs)
    emb = embree.closest(origins, dirs)
    figures = {"scene": scene.name, "bvh": bvh, "triangles": int(len(scene.triangles)), "rays": int(len(origins)),
               "camera_rays": int(len(co)), "random_rays": int(len(ro)), "resolution": (width, height)}
    closest, excused, unexplained = _closest_figures(origins, dirs, dev, emb, embree.triangles)
    figures.update(closest)
    figures["camera_disagreements"] = int((dev[1] != emb[1])[: len(co)].sum())
    figures["camera_unexplained"] = int(unexplained[: len(co)].sum())

    # Any hit on random segments: the random rays with tmax uniform in (0, scene diagonal).
    tmax = (rng.random(len(ro)) * device_scene.extent).astype(np.float32)
    tmax = np.maximum(tmax, np.float32(1e-6 * device_scene.extent))
    blocked = device.occluded(ro, rd, tmax), embree.occluded(ro, rd, tmax)
    sl = slice(len(co), len(origins))
    any_figures, any_unexplained = _any_hit_figures(tuple(a[sl] for a in dev), tuple(a[sl] for a in emb),
                                                    tmax, blocked, excused[sl])
    figures.update(any_figures)
    figures["excused_fraction"] = figures["excused"] / max(len(origins), 1)
    figures["excused_rounding_fraction"] = figures["excused_rounding"] / max(len(origins), 1)
    figures["any_excused_fraction"] = figures["any_excused"] / max(len(ro), 1)
    figures["unexplained_examples"] = (
        _closest_examples(origins, dirs, dev, emb, unexplained, max_examples)
        + _segment_examples(ro, rd, tmax, blocked, dev, emb, len(co), any_unexplained, max_examples))
    figures["seconds"] = time.perf_counter() - start
    return figures


def _resolution_of(scene, resolution):
    """(width, height) of the camera rays: the scene's camera, a square side, or a pair."""
    if resolution is None:
        width, height = scene.camera.width, scene.camera.height
    elif isinstance(resolution, (int, np.integer)):
        width, height = int(resolution), int(resolution)
    else:
        width, height = (int(r) for r in resolution)
    return camera_size(width, height)     # render's memory estimate, before the rays are made


def _closest_figures(origins, dirs, dev, emb, triangles):
    """The closest-hit figures of the module doc, and per ray whether a disagreement is excused
    or unexplained: (figures, excused, unexplained)."""
    td, pd, _, _ = dev
    te, pe, _, _ = emb
    hd, he = pd >= 0, pe >= 0
    agree = pd == pe
    excusable, edge, tie = _excused_closest(dev, emb)
    disagree = ~agree
    excused = disagree & excusable
    unexplained = disagree & ~excusable
    # Ties (not near an edge) whose two triangles the ray provably hits at the same distance.
    tie_only = np.flatnonzero(disagree & tie & ~edge)
    proven = np.zeros(len(origins), bool)
    proven[tie_only] = verified_ties(origins[tie_only], dirs[tie_only], pd[tie_only], pe[tie_only], triangles)
    both = agree & hd
    rel, conditioned = _distance_errors(origins[both], dirs[both], td[both], te[both], triangles[pe[both]])
    figures = {
        "hits_device": int(hd.sum()),
        "hits_embree": int(he.sum()),
        "hit_miss_agree": int((hd == he).sum()),
        "hit_miss_disagree": int((hd != he).sum()),
        "prim_agree": int(agree.sum()),
        "disagreements": int(disagree.sum()),
        "excused": int(excused.sum()),
        "excused_edge": int((disagree & edge).sum()),
        "excused_tie": int((disagree & tie & ~edge).sum()),
        "ties_verified": int(proven.sum()),
        "excused_rounding": int((excused & ~proven).sum()),
        "unexplained": int(unexplained.sum()),
        "agreeing_hits": int(both.sum()),
        "max_rel_t_error": float(rel.max()) if len(rel) else 0.0,
        "rel_t_error_above_tie": int((rel > TIE_RELATIVE).sum()),
        "max_t_error_conditioned": float(conditioned.max()) if len(conditioned) else 0.0,
    }
    return figures, excused, unexplained


def _distance_errors(origins, dirs, t_device, t_embree, triangles):
    """Over hits on the same triangle: the relative distance error, and the error without the
    distance's condition number (module doc: coordinates' size over |cos|)."""
    t64, e64 = t_device.astype(np.float64), t_embree.astype(np.float64)
    dt = np.abs(t64 - e64)
    rel = dt / np.maximum(e64, 1e-30)
    hit_point = origins.astype(np.float64) + t64[:, None] * dirs
    scale = np.maximum(np.maximum(e64, np.abs(origins).max(1)), np.abs(hit_point).max(1))
    tri = triangles.astype(np.float64)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    cos = np.abs(np.einsum("ij,ij->i", normal, dirs.astype(np.float64)))
    return rel, dt * cos / scale


def _any_hit_figures(dev, emb, tmax, blocked, excused):
    """The any-hit figures of the segments (module doc), given each intersector's closest hit on
    the same rays and which segments each found blocked: (figures, unexplained per segment)."""
    td, pd, ud, vd = dev
    te, pe, ue, ve = emb
    bd, be = blocked
    hd, he = pd >= 0, pe >= 0
    td_s, te_s = td.astype(np.float64), te.astype(np.float64)
    on_d = hd & (td_s <= tmax * (1 + TIE_RELATIVE))
    on_e = he & (te_s <= tmax * (1 + TIE_RELATIVE))
    near_d = on_d & (edge_distance(ud, vd) < EDGE_BARYCENTRIC)
    near_e = on_e & (edge_distance(ue, ve) < EDGE_BARYCENTRIC)
    with np.errstate(invalid="ignore"):
        at_end = (hd & (np.abs(td_s - tmax) <= TIE_RELATIVE * tmax)) | (he & (np.abs(te_s - tmax) <= TIE_RELATIVE * tmax))
    any_excusable = near_d | near_e | at_end | excused
    any_disagree = bd != be
    any_unexplained = any_disagree & ~any_excusable
    figures = {
        "segments": int(len(tmax)),
        "blocked_device": int(bd.sum()),
        "blocked_embree": int(be.sum()),
        "any_agree": int((~any_disagree).sum()),
        "any_disagreements": int(any_disagree.sum()),
        "any_excused": int((any_disagree & any_excusable).sum()),
        "any_unexplained": int(any_unexplained.sum()),
        # Consistency of each intersector with itself: blocked iff its closest hit is on the segment.
        "device_any_vs_closest_mismatch": int((bd != (hd & (td_s < tmax))).sum()),
    }
    return figures, any_unexplained


def _closest_examples(origins, dirs, dev, emb, unexplained, max_examples):
    td, pd, ud, vd = dev
    te, pe, ue, ve = emb
    return [{"ray": int(i), "origin": origins[i].tolist(), "dir": dirs[i].tolist(),
             "device": (float(td[i]), int(pd[i]), float(ud[i]), float(vd[i])),
             "embree": (float(te[i]), int(pe[i]), float(ue[i]), float(ve[i]))}
            for i in np.flatnonzero(unexplained)[:max_examples]]


def _segment_examples(ro, rd, tmax, blocked, dev, emb, first, unexplained, max_examples):
    """Segments with an unexplained any-hit disagreement; `first`: the index of the first random ray."""
    examples = []
    for j in np.flatnonzero(unexplained)[:max_examples]:
        i = first + j
        examples.append({"segment": int(j), "origin": ro[j].tolist(), "dir": rd[j].tolist(),
                         "tmax": float(tmax[j]), "device_blocked": bool(blocked[0][j]),
                         "embree_blocked": bool(blocked[1][j]),
                         "device_closest": (float(dev[0][i]), int(dev[1][i])),
                         "embree_closest": (float(emb[0][i]), int(emb[1][i]))})
    return examples


def format_figures(f):
    """A short human-readable summary of compare_with_embree's figures."""
    return (f"{f['scene']} ({f['bvh']} BVH): {f['rays']} rays ({f['camera_rays']} camera + "
            f"{f['random_rays']} random), {f['triangles']} triangles\n"
            f"  closest: hits device/embree {f['hits_device']}/{f['hits_embree']}, "
            f"hit/miss agree {f['hit_miss_agree']}, prim agree {f['prim_agree']}, "
            f"disagree {f['disagreements']} (excused {f['excused']}: edge {f['excused_edge']}, "
            f"tie {f['excused_tie']} of which {f['ties_verified']} proven coplanar ties; "
            f"unexplained {f['unexplained']})\n"
            f"  distance on agreeing hits: max rel error {f['max_rel_t_error']:.3g} "
            f"({f['rel_t_error_above_tie']} of {f['agreeing_hits']} above {TIE_RELATIVE:g}: "
            f"short or grazing hits), conditioned error {f['max_t_error_conditioned']:.3g}\n"
            f"  any-hit: {f['segments']} segments, blocked device/embree "
            f"{f['blocked_device']}/{f['blocked_embree']}, agree {f['any_agree']}, "
            f"disagree {f['any_disagreements']} (excused {f['any_excused']}, "
            f"unexplained {f['any_unexplained']})\n"
            f"  {f['seconds']:.1f} s")
