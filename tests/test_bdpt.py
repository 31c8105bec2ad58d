"""Bidirectional path tracing: MIS weights, vertex scatter, the two connect phases, SIMD figures,
and the image summed on the device."""
import dataclasses

import numpy as np
import pyopencl as cl
import pytest

import toolkit
from toolkit.opencl import program
from toolkit.opencl.device import get_queue
from toolkit.opencl.device_film import has_fp64
from toolkit.opencl.device_scene import DeviceScene
from toolkit.peers.embree import EmbreeIntersector
from toolkit.core.layout import BDPT_VERTEX, VertexFlag
from toolkit.verify.same_image import SAME_DEVICE_BDPT
from toolkit.techniques import BdptParallelConnect
from planted_nan import plant_nan_in_every_connect_phase

VERTEX_DELTA = VertexFlag.DELTA   # flags of BdptVertex (toolkit/core/layout.py, emitted into layout.h)
VERTEX_LIGHT = VertexFlag.LIGHT


def run(queue, scene, cls, spp=4, res=(16, 16), seed=1, **options):
    tech = cls(queue, DeviceScene(queue, scene), **options)
    film = tech.render(*res, spp, seed=seed)
    return tech, film


@pytest.mark.parametrize("scene_name", ["cornell_box", "cornell_spheres"])
def test_mis_weights_of_all_strategies_sum_to_one(queue, scene_name, request):
    """Real paths from the device's eye subpaths that end on a light (front side): for every
    way to split such a path into a light and an eye subpath, the device evaluates the
    strategy's MIS weight with the renderers' own connect_strategy(); they must sum to 1."""
    scene = request.getfixturevalue(scene_name)
    tech, _ = run(queue, scene, BdptParallelConnect, spp=1, res=(64, 64))
    paths = tech.eye_paths_to_lights(200)
    assert len(paths) >= 50, "too few eye paths reached a light to test"
    sums, lengths = [], []
    for w in split_weights(queue, tech, scene, paths):
        assert np.all(w >= 0) and np.all(w <= 1 + 1e-5)
        sums.append(float(w.sum()))
        lengths.append(len(w))
    sums = np.array(sums)
    print(f"{scene_name}: {len(sums)} paths of {min(lengths)}..{max(lengths)} vertices, "
          f"sum of weights {sums.min():.6f}..{sums.max():.6f}")
    # float32 ratios: 1e-4 (every path measured sums to 1 within 1e-6).
    assert np.all(np.abs(sums - 1) < 1e-4), sums[np.abs(sums - 1) >= 1e-4]


def split_weights(queue, tech, scene, paths, resolution=(64, 64)):
    """For each path (light -> eye order), the MIS weight of every split s = 0 .. n - 1
    (s light vertices), from the device's connect_strategy() (cl/bdpt_test.cl)."""
    ds = tech.scene
    built = program.build(queue, "bdpt_test.cl", dict(tech.scene.features(), MAX_VERTICES=tech.max_vertices))
    kernel = program.kernel(built, "bdpt_test_mis_splits")
    camera = ds.camera(*resolution)
    mf = cl.mem_flags
    for path in paths:
        n = len(path)
        path_buf = cl.Buffer(queue.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(path))
        scratch = [cl.Buffer(queue.context, mf.READ_WRITE, BDPT_VERTEX.dtype.itemsize * n * tech.max_vertices)
                   for _ in range(2)]
        weights = cl.Buffer(queue.context, mf.READ_WRITE, 4 * n)
        program.launch(queue, kernel, n, *ds.args(), camera, np.int32(n), path_buf, *scratch, weights)
        w = np.empty(n, np.float32)
        cl.enqueue_copy(queue, w, weights)
        yield w


def seen_by_camera(tech, scene, points, resolution=(64, 64)):
    """Whether the camera sees each point (device coordinates): it projects inside the image
    and Embree finds nothing between the pinhole and the point."""
    camera = tech.scene.camera(*resolution)
    forward, right, up = (camera[k][:3].astype(np.float64) for k in ("forward", "right", "up"))
    origin = camera["origin"][:3].astype(np.float64)
    d = np.asarray(points, np.float64) - origin
    dist = np.linalg.norm(d, axis=1)
    w = d / dist[:, None]
    ahead = w @ forward
    on_plane = w / np.where(ahead > 0, ahead, 1.0)[:, None]
    inside = ((ahead > 0) & (np.abs(on_plane @ right / (right @ right)) < 1)
              & (np.abs(on_plane @ up / (up @ up)) < 1))
    embree = EmbreeIntersector(scene, center=tech.scene.center)
    origins = np.repeat(origin[None].astype(np.float32), len(w), 0)
    occluded = embree.occluded(origins, w.astype(np.float32), (dist * (1 - 1e-4)).astype(np.float32))
    return inside & ~occluded


def test_caustic_paths_go_to_light_tracing(queue, cornell_spheres):
    """Caustic paths light -> glass -> glass -> floor -> camera (L S S D E): light tracing
    (s = 4, t = 1) samples them far better than an eye path that must hit the light through
    the sphere (s = 0), and MIS must say so. With pbrt-v3's convention (density 0, then 1, at
    specular bounces) the eye path got about 90% of these paths and the caustic stayed as
    noisy as in a path tracer; with Veach's density for the delta (cl/bdpt.h) it is the
    other way round.

    A light subpath's floor point that the camera cannot see (about a quarter of them lie
    behind a sphere) is no path of the image: every strategy's contribution is zero, and
    light tracing, the only one that tests visibility in this kernel, must give it nothing.
    Which paths the camera sees is decided by Embree, not by the weights, so every path
    that is seen must have weights that sum to one."""
    tech, _ = run(queue, cornell_spheres, BdptParallelConnect, spp=1, res=(64, 64))
    eye, _, light, light_count = tech.read_vertices()
    camera = eye[0, 0]
    paths = []
    for slot in range(len(light_count)):
        if light_count[slot] >= 4:
            y = light[slot, :4]
            delta = (y["flags"] & VERTEX_DELTA) != 0
            if delta[1] and delta[2] and not delta[3]:
                paths.append(np.concatenate([y, [camera]]))
    weights = np.array(list(split_weights(queue, tech, cornell_spheres, paths)))
    seen = seen_by_camera(tech, cornell_spheres, [p[3]["pos"][:3] for p in paths])
    assert np.all(weights[~seen, 4] == 0), "light tracing connected to a floor point the camera cannot see"
    weights = weights[seen]
    assert len(weights) >= 20, f"only {len(weights)} caustic paths seen by the camera"
    sums = weights.sum(1)
    assert np.all(np.abs(sums - 1) < 1e-4), sums[np.abs(sums - 1) >= 1e-4]
    print(f"{len(weights)} caustic paths seen ({int((~seen).sum())} hidden): mean weight of light tracing "
          f"{weights[:, 4].mean():.3f}, of the eye path {weights[:, 0].mean():.3f}")
    # The strategies in between connect at a specular vertex and must get nothing.
    assert np.all(weights[:, 1:4] == 0)
    assert weights[:, 4].mean() > 0.9


def valid_vertices(vertices, counts):
    return np.concatenate([vertices[slot, :counts[slot]] for slot in range(len(counts))]).tobytes()


def test_coalesced_and_direct_scatter_write_identical_vertex_memory(queue, cornell_spheres):
    a, film_a = run(queue, cornell_spheres, BdptParallelConnect, coalesced_scatter=True)
    b, film_b = run(queue, cornell_spheres, BdptParallelConnect, coalesced_scatter=False)
    ea, eca, la, lca = a.read_vertices()
    eb, ecb, lb, lcb = b.read_vertices()
    assert np.array_equal(eca, ecb) and np.array_equal(lca, lcb)
    assert valid_vertices(ea, eca) == valid_vertices(eb, ecb)
    assert valid_vertices(la, lca) == valid_vertices(lb, lcb)
    np.testing.assert_array_equal(film_a.image(), film_b.image())


@pytest.mark.parametrize("scene_name", ["cornell_box", "cornell_spheres"])
def test_naive_and_parallel_connect_compute_the_same_image(scene_name, request):
    scene = request.getfixturevalue(scene_name)
    a = toolkit.render(scene, technique="bdpt_naive_connect", spp=8, seed=3, resolution=(16, 16)).image
    b = toolkit.render(scene, technique="bdpt_parallel_connect", spp=8, seed=3, resolution=(16, 16)).image
    np.testing.assert_allclose(a, b, *SAME_DEVICE_BDPT)   # float32 sums on the device against float64 on the host


@pytest.fixture(scope="module")
def bdpt_figures(cornell_box):
    """SIMD counters on cornell_box at W = 32."""
    return {t: toolkit.render(cornell_box, technique=t, spp=16, seed=0, resolution=(64, 64)).stats
            for t in ("bdpt_naive_connect", "bdpt_parallel_connect")}


def test_connect_phase_efficiency_like_the_talk(bdpt_figures):
    naive = bdpt_figures["bdpt_naive_connect"]["simd_efficiency"]
    parallel = bdpt_figures["bdpt_parallel_connect"]["simd_efficiency"]
    print(naive, parallel)
    assert naive["connect"] <= 0.30          # talk: ~17%
    assert parallel["connect"] >= 0.97       # talk: ~99%
    for stats in bdpt_figures.values():
        assert stats["simd_efficiency"]["walk"] >= 0.97
        assert stats["walk_efficiency_without_compaction"] < stats["simd_efficiency"]["walk"]


def test_every_pixel_gets_its_samples_and_no_nan(cornell_spheres):
    for t in ("bdpt_naive_connect", "bdpt_parallel_connect"):
        r = toolkit.render(cornell_spheres, technique=t, spp=6, seed=2, resolution=(13, 7))
        assert r.stats["samples_per_pixel"] == [6, 6]
        assert r.stats["nonfinite_samples"] == 0 and np.isfinite(r.image).all()


class KeepConnections:
    """A sink of the caller's own: it keeps every connect phase's Connections, read back in
    `add` (the next connect phase reuses their device memory)."""

    def __init__(self):
        self.phases = []

    def add(self, connections):
        connections.values, connections.pixels     # read now
        self.phases.append(connections)


@pytest.mark.parametrize("scale", [1.0, 2.0 ** -20, 2.0 ** 20])
def test_the_evaluator_hands_every_connect_phase_to_the_callers_sink(queue, cornell_box, scale):
    """BdptEvaluator.evaluate gives each connect phase's records to the sink it is given (mlt's
    chains, bdpt's ImageSink): a sink that keeps them gets the records of every sample of the
    pass, each with its slot's sample id, and their sum per pixel is the image the technique
    renders from the same samples (its own pass, through ImageSink's sums on the device and the film).
    With the lights `scale`d to about 1e-6 and 1e6 (powers of two: every float32 record scales
    exactly), the device's sums keep their precision at both ends."""
    from toolkit.techniques.bdpt_evaluator import BdptEvaluator, per_pixel_sums
    from toolkit.techniques.bdpt_parallel_connect import ParallelConnect
    scene = dataclasses.replace(cornell_box, emission_of=cornell_box.emission_of * scale)
    tech = BdptParallelConnect(queue, DeviceScene(queue, scene), count_simd=False, pool_size=64)
    ctx = tech.bdpt_context
    evaluator = BdptEvaluator(ctx, ParallelConnect(ctx, read_slots=True), tech.pool_size, 0.6, tech.max_vertices)
    camera, pixels, spp = tech.scene.camera(8, 8), 64, 4
    budget = pixels * spp
    kept = KeepConnections()
    evaluator.evaluate(evaluator.start_pass(camera, np.uint32(3), 0, budget), kept)
    rendered = tech.render(8, 8, spp, seed=3).image()     # one pass (budget < target_batch), sample ids 0 ..
    assert len(kept.phases) > budget // 64            # the pool of 64 connects several times
    samples = np.concatenate([np.repeat(c.slots["sample_id"], c.slot_records) for c in kept.phases
                              if c.slots is not None])
    assert set(np.unique(samples)) <= set(range(budget)) and len(np.unique(samples)) > 0.9 * budget
    values = np.concatenate([c.values for c in kept.phases])
    at = np.concatenate([c.pixels for c in kept.phases])
    assert len(samples) == len(at)                     # one sample id per record
    ours = per_pixel_sums(values[at >= 0, :3], at[at >= 0], pixels).reshape(8, 8, 3) / spp
    assert rendered.sum() > 0
    # The same float32 records, summed in float64 here. On the device (cl/record_film.cl) each is
    # rounded to a multiple of 2^-48 (by at most 2^-49), their exact sum rounded once to float32
    # (by at most half an ulp, 2^-24 relative); float64's own rounding here is far below both.
    records = np.bincount(at[at >= 0], minlength=pixels).reshape(8, 8, 1)
    allowed = 2.0 ** -24 * ours + 1.01 * records * 2.0 ** -49 / spp
    assert np.all(np.abs(ours - rendered) <= allowed), np.abs(ours - rendered).max()


@pytest.mark.parametrize("technique", ["bdpt_naive_connect", "bdpt_parallel_connect"])
def test_one_seed_gives_the_same_bits_with_either_atomics(cornell_spheres, technique, monkeypatch):
    """The records are summed on the device with integer atomics (toolkit/opencl/record_film.py):
    in whatever order the work-items add them, two renders with one seed give the same bits, and
    a device without 64-bit atomics (32-bit words with carries) gives those bits too. Two passes,
    so the pass read one pass behind reaches the film too."""
    from toolkit.opencl import record_film

    def image(word_bits=None):
        if word_bits:
            monkeypatch.setattr(record_film, "film_word_bits", lambda device: word_bits)
        r = toolkit.render(cornell_spheres, technique=technique, spp=2, seed=7, resolution=(24, 16),
                           count_simd=False, technique_options={"pass_spp": 1})
        assert r.stats["nonfinite_samples"] == 0 and np.isfinite(r.image).all() and r.image.sum() > 0
        return r.image.view(np.uint64)
    first = image()
    assert np.array_equal(image(), first)
    assert np.array_equal(image(32), first)


@pytest.mark.parametrize("exponent", [-20, 20])
def test_a_scene_a_million_times_darker_or_brighter_gives_the_same_bits_scaled(cornell_box, exponent):
    """Lights scaled by 2^-20 (about 1e-6) or 2^20 (about 1e6): every float32 record scales exactly,
    and the film counts them in units of the brightest light (record_film.unit_exponent_for), so
    the image is the same bits scaled: the device's sums lose nothing at either end."""
    def image(scale):
        scene = dataclasses.replace(cornell_box, emission_of=cornell_box.emission_of * scale)
        return toolkit.render(scene, technique="bdpt_parallel_connect", spp=2, seed=4, resolution=(16, 12),
                              count_simd=False).image
    unit = image(1.0)
    assert np.array_equal(image(2.0 ** exponent), unit * 2.0 ** exponent)


@pytest.mark.parametrize("technique", ["bdpt_naive_connect", "bdpt_parallel_connect"])
def test_a_non_finite_record_is_dropped_and_reported_never_in_the_image(cornell_box, technique, monkeypatch):
    """A NaN planted in the first record of every connect phase (on the device, before the sink
    adds it): each is counted and reported (DroppedSamplesWarning), and the image stays finite.
    A pool of a third of the pass's samples makes several connect phases."""
    from toolkit.api import DroppedSamplesWarning
    from toolkit.techniques import bdpt_base
    planted = plant_nan_in_every_connect_phase(monkeypatch, bdpt_base.ImageSink)
    with pytest.warns(DroppedSamplesWarning):
        r = toolkit.render(cornell_box, technique=technique, spp=2, seed=1, resolution=(12, 8), count_simd=False,
                           technique_options={"pool_size": 64})
    assert len(planted) > 1 and r.stats["nonfinite_samples"] == len(planted)
    assert np.isfinite(r.image).all() and r.image.sum() > 0


@pytest.mark.parametrize("technique", ["bdpt_naive_connect", "bdpt_parallel_connect"])
def test_the_host_reads_a_pixel_per_pass_not_the_records(cornell_box, technique, monkeypatch):
    """The records stay on the device (toolkit/opencl/record_film.py): besides the walk's few
    bytes of counters, the host reads the film once, at the end, where the device has float64
    (device_film.py DevicePassFilm adds the passes there), else one float4 per pixel per pass.
    Before, every record came back (93 to 306 bytes per sample, results/gpu.md)."""
    width, height, spp = 24, 16, 4
    reads, copy = [], cl.enqueue_copy

    def counting(queue, dest, src, **kwargs):
        if isinstance(dest, np.ndarray):
            reads.append(dest.nbytes)
        return copy(queue, dest, src, **kwargs)
    monkeypatch.setattr(cl, "enqueue_copy", counting)
    toolkit.render(cornell_box, technique=technique, spp=spp, seed=2, resolution=(width, height),
                   count_simd=False, technique_options={"pass_spp": 1})
    pixels = width * height
    image_reads = [n for n in reads if n == 16 * pixels]
    film_reads = [n for n in reads if n in (48 * pixels, 8 * pixels)]   # DeviceFilm.read: the sums, the counts
    if has_fp64(get_queue().device):
        assert not image_reads and sorted(film_reads) == [8 * pixels, 48 * pixels]   # the film, once
    else:
        assert len(image_reads) == spp and not film_reads   # one per pass
    assert all(n <= 64 for n in reads if n not in (16 * pixels, 48 * pixels, 8 * pixels)), sorted(reads)[-5:]


@pytest.mark.parametrize("technique", ["bdpt_naive_connect", "bdpt_parallel_connect"])
def test_a_pass_never_waits_for_a_count_and_reads_once_per_connect_phase(cornell_box, technique, monkeypatch):
    """The connect decision stays on the device (bdpt_evaluator.py): the host lists the terminated
    samples there and reads what it needs (listed slots, records, the walk's counters) once per
    listing, LAG steps later. So no read blocks, and a render reads once per connect phase, once
    per pass for its image, and a few times more for listings that found too few terminated (a
    pass's first, and its end's longest subpaths). Before: three blocking reads per connect phase
    and a read of the walk's counters every step. A pool of 64 makes many connect phases."""
    from toolkit.opencl.traffic import Traffic
    from toolkit.techniques import bdpt_base
    phases, add = [], bdpt_base.ImageSink.add

    def counted(sink, connections):
        phases.append(connections.count)
        add(sink, connections)
    monkeypatch.setattr(bdpt_base.ImageSink, "add", counted)
    toolkit.render(cornell_box, technique=technique, spp=1, resolution=(8, 8), count_simd=False)   # built
    phases.clear()
    passes = 2
    with Traffic() as traffic:
        toolkit.render(cornell_box, technique=technique, spp=4, seed=2, resolution=(24, 16), count_simd=False,
                       technique_options={"pool_size": 64, "pass_spp": 4 // passes})
    phases = [n for n in phases if n]
    assert len(phases) > 20
    assert traffic.blocking_reads == 0 and traffic.drains == passes     # the drains: each pass's image, read late
    assert passes + len(phases) <= traffic.reads <= passes + len(phases) + 3 * passes


@pytest.mark.parametrize("technique", ["bdpt_naive_connect", "bdpt_parallel_connect"])
def test_the_pool_size_changes_the_schedule_not_the_image_bits(cornell_box, technique):
    """Every sample of a pass is connected exactly once, whenever its connect phase comes: a pool of
    40 (many connect phases, samples that terminate while others are listed wait for the next one,
    listings that find too few) gives the same bits as a pool that holds the whole pass, because
    a sample's records depend only on its id and the film's sums are exact (record_film.py)."""
    def image(pool):
        return toolkit.render(cornell_box, technique=technique, spp=2, seed=6, resolution=(16, 12), count_simd=False,
                              technique_options={"pool_size": pool}).image
    whole = image(16 * 12 * 2)
    assert whole.sum() > 0 and np.array_equal(image(40), whole)
