"""Metropolis light transport: many independent primary-sample-space chains (Kelemen et al. 2002)
over the bidirectional estimator, as in the talk's slides "Metropolis Light Transport" and
"Startup Bias". Kernels: cl/mlt.cl (cl/mlt.h: mutation and acceptance; the BDPT kernels of
cl/bdpt_parallel_connect.cl built with -DMLT=1 read their uniforms from the chains' vectors).

One iteration, read like the slide:
    mutate every chain (large step with probability `large_step`, else a small step);
    evaluate all proposals as one batch of BDPT samples (compacted walks, parallel connect);
    accept or reject per chain;
    splat the proposal with weight a and the current state with weight 1 - a.

The estimator. A sample x (a point of primary sample space [0, 1)^D: the image position, the
light sample, every scattering decision) has the contribution h_j(x) to pixel j, the sum of
all its MIS-weighted strategies (s, t) that land there (t = 1 lands anywhere), and the scalar
contribution f(x) = luminance(sum_j h_j(x)). Each chain's states follow the density f / b with
b = integral of f over [0, 1)^D, so with M mutations in all, proposals y_i with acceptance a_i
and current states x_i,

    I_j = P * b * E_{f/b}[h_j / f]  ~  P * b / M * sum_i ( a_i h_j(y_i) / f(y_i) + (1 - a_i) h_j(x_i) / f(x_i) )
                                                  (times the chain's weight w_c / mean(w) for start = resample)

(P = pixels: the image position is uniform over the whole image, so a sample reaches pixel j
with probability 1 / P; Kelemen eq. 7 with Veach's expected-value splatting, sec. 11.5).
b is estimated on the fly from the large steps, which are ordinary BDPT samples:
b ~ (1 / L) sum over the L large steps of f(y) (the start's samples count too).

Kelemen's combination (`combine`, on by default; Kelemen et al. 2002, sec. 5). The large steps
are plain BDPT samples, uniform in primary sample space: with probability p = large_step per
mutation, a second sampling technique beside the Metropolis states (density f / b per
mutation). Both estimate I_j, and the balance heuristic joins them: the Metropolis technique's
weight at z is (f(z) / b) / (f(z) / b + p), the large steps' p / (f(z) / b + p), so

    I_j ~ P / M * sum_i ( b * [a_i h_j(y_i) / (f(y_i) + p b') + (1 - a_i) h_j(x_i) / (f(x_i) + p b')]
                          + [y_i is a large step] * b' h_j(y_i) / (f(y_i) + p b') ).

The weights sum to 1 whatever b' is (b' here only sets the balance), so it is b as estimated
before the iteration, and the Metropolis sum is still scaled by the final b. Where f is small
against p b (dark pixels, which few Metropolis states visit) the large steps carry the
estimate like BDPT would; where f is large the Metropolis states do. With combine = False (or
p -> 0) it is the plain estimator above. The start's samples only go into b.

The start. `naive` (the talk): a chain starts at one large step, distributed like a BDPT
sample (uniform in primary sample space), not like f / b: the first mutations of every chain
are biased towards where samples are many rather than bright (startup bias), and with many
chains and few mutations each, that bias dominates (toolkit/measure/mlt_bias.py measures it).
`resample` (Veach 1997, sec. 11.3.3): chain c draws N candidates (large steps) and keeps one
with probability f_k / sum_k f_k; with the weight w_c = (1/N) sum_k f_k, E[w_c g(x_c)] equals
the integral of f g for every g, at the start and (the mutations keep f / b invariant) at every
later iteration: no startup bias in expectation. Each chain's splats are weighted by
w_c / mean_c(w_c) (a ratio estimator: its bias is O(1 / (chains x N)), far below the startup
bias it removes), so the image still sums to b from all large steps. Its cost: the weights
vary as much as a mean of N values of f does (a lot where f is heavy-tailed: covered_lamp),
and that variance stays in the image.
`pool` (the bootstrap of pbrt-v3's MLT): the chains draw their N candidates each as for
`resample`, but every chain then starts at a candidate drawn from all chains' candidates
together in proportion to f (systematic resampling: chains x N candidates, `chains` evenly
spaced draws on the cumulative f), and every chain weighs 1. The chains then start distributed
like f / b up to the resampling of a finite pool: a bias of O(1 / (chains x N)), like the ratio
above, with no weights to add variance. A bright candidate may start several chains; they part
with their first mutations.

Splats (pixel, value) are added on the host in float64, like the t = 1 records of BDPT
(bdpt_base.per_pixel_sums): no float atomics. Each chain's current state keeps its records
on the host until it is replaced.

Options (keyword arguments of toolkit.render(..., options=...)):

| option | default | meaning |
| --- | --- | --- |
| `chains` | the BDPT pool size (4096 on a CPU; `devices` shows it) | independent chains; 1 .. 2^18 (`mlt.chains`), at most the mutations of the render |
| `large_step` | 0.3 | probability of a large step (every dimension fresh) |
| `small_step` | 1/16 | the largest size of a small step, Kelemen's s2 (the smallest, s1, is s2 / 16); see SMALL_STEP |
| `start` | `naive` | `naive`: each chain starts at one large step (the talk; biased at first). `resample`: at one of its own `candidates` large steps, chosen in proportion to f, and weighted. `pool`: at one of all chains' candidates, chosen in proportion to f, weight 1. At equal time (30 s, 32x32, two-core CPU) pool's RMSE was 0.0064 against naive's 0.0066 on covered_lamp and 0.0091 against 0.019 on cornell_spheres, where naive chains are still biased; on cornell_box, where they are not, naive was ahead (0.0060 against 0.0072). At 10 s (3 repetitions, results/issue10_mlt.md) pool removes naive's detected bias on covered_lamp and cornell_spheres but adds variance (chains that start at the same bright candidate): RMSE 0.113 against 0.108 (covered_lamp), 0.072 against 0.128 (cornell_spheres). `naive` stays the default, as in the talk: its start is one iteration |
| `candidates` | 16 | large steps per chain for `start = resample` or `pool` (`mlt.candidates`) |
| `max_dims` | 128 | primary-sample dimensions a chain stores: 8 + 8 per vertex of the longer subpath, so 128 holds subpaths of 16 vertices (`mlt.max_dims`). A path that reads more gets fresh random numbers for the extra dimensions at every iteration (cl/mlt_proposals.h): still correct, and counted (`overflow_proposals`) |
| `combine` | true | Kelemen's combination: the large steps also splat as BDPT samples, joined with the Metropolis states by the balance heuristic (above) |
| `time_limit` | none | seconds: stop after the iteration that passes it (the image holds the mutations made so far) |
| BDPT options | | `pool_size` (the device's, as for bdpt_parallel_connect: with the default chains an iteration is one pool-full; a pool of a quarter of the chains, which regenerates like a BDPT pass, measured no faster on covered_lamp 64x64), `regenerate_fraction` (default 1 where the pool holds every chain: one connect phase per iteration; else 0.6 as for BDPT), `coalesced_scatter` as for bdpt_parallel_connect |

spp means mutations: a render of spp samples per pixel makes spp x pixels mutations in all
(iterations of `chains` mutations; the last may use fewer chains), fewer if `time_limit` stops it. The start's samples come
on top. The image has no standard error of its own (one pass; MLT samples are correlated):
compare independent runs (seeds), as tests/test_mlt.py and toolkit/measure/mlt_bias.py do.
"""
import time
from dataclasses import dataclass

import numpy as np
import pyopencl as cl

from toolkit.core.film import Film
from toolkit.core.layout import BDPT_SLOT, LUMINANCE_WEIGHTS, MLT_CHAIN, MLT_ITERATION, MltMode
from toolkit.core.sample_dims import BDPT_FIRST_SCATTER_DIM, used_dims   # the dimension table the kernels read
from toolkit.core.validate import LIMITS, InputError, finite_number, whole_number
from toolkit.techniques.bdpt_base import per_pixel_sums
from toolkit.techniques.bdpt_parallel_connect import BdptParallelConnect

STARTS = ("naive", "resample", "pool")


SMALL_STEP = 1 / 16
# The largest small step, Kelemen's s2 (his paper: 1/64, with s1 = 1/1024). On covered_lamp,
# 32x32, 4,096 chains, 64 mutations each, pool start, 6 runs, the relative squared error of one
# run was 0.0216 with s2 = 1/64 and 0.0136 with 1/16 (1/32: 0.0167, 1/8: 0.0161 at large_step 0.1):
# paths through the slit tolerate larger moves than the 1/64 that Kelemen tuned for.


def step_defines(small_step):
    """The small step's sizes for cl/mlt.h: s2 = small_step, s1 = s2 / 16 (Kelemen's ratio)."""
    return {"MLT_S2": float(small_step), "MLT_S1": float(small_step) / 16}


@dataclass
class Chains:
    """The chains' device memory and the host's view of their current states."""
    count: int
    current: cl.Buffer       # float[max_dims][count]: the current states' primary-sample vectors
    proposal: cl.Buffer      # float[max_dims][count]: this iteration's proposals
    records: cl.Buffer       # MltChain[count]
    f_proposal: cl.Buffer    # float[count], written by the host
    dims_proposal: cl.Buffer  # int[count], written by the host
    iteration: int = 0
    f_current: np.ndarray = None        # float64 f of each current state
    cur_values: np.ndarray = None       # the current states' records: (n, 3) float64 values,
    cur_pixels: np.ndarray = None       #   their pixels
    cur_chain: np.ndarray = None        #   and their chains
    splats: np.ndarray = None           # (pixels, 3) float64 sum of the Metropolis splats (times b at the end)
    large_splats: np.ndarray = None     # (pixels, 3) float64 sum of the large steps' own splats (combine)
    candidate_sum: np.ndarray = None    # start = resample: sum of f over each chain's candidates
    weight: np.ndarray = None           # each chain's splat weight: 1, or w_c / mean(w) (resample)
    large_sum: float = 0.0              # sum of f over the large steps (for b)
    large_count: int = 0
    accepted: int = 0
    mutations: int = 0
    overflow: int = 0                   # proposals that read more than max_dims dimensions
    nonfinite: int = 0


class Mlt(BdptParallelConnect):
    name = "mlt"
    source = "mlt.cl"
    family = "mlt"

    def __init__(self, queue, device_scene, chains=None, large_step=0.3, start="naive", candidates=16,
                 max_dims=128, combine=True, time_limit=None, small_step=SMALL_STEP, **kwargs):
        self.chain_count = whole_number("mlt.chains", chains, "chains") if chains is not None else None
        self.large_step = finite_number("mlt.large_step", large_step, "large_step")
        if start not in STARTS:
            raise InputError(f"start must be one of {', '.join(STARTS)}, got {start!r}")
        self.start = start
        self.candidates = whole_number("mlt.candidates", candidates, "candidates")
        self.max_dims = whole_number("mlt.max_dims", max_dims, "max_dims")
        if combine not in (True, False):
            raise InputError(f"combine must be true or false, got {combine!r}")
        self.combine = bool(combine)
        self.time_limit = None if time_limit is None else finite_number("mlt.time_limit", time_limit, "time_limit")
        if device_scene.scene.clamp is not None:
            raise InputError("mlt does not clamp (scene integrator.clamp is set): every Metropolis splat already has "
                             "the same brightness b / M, so there are no fireflies to cap, and a capped f would only "
                             "change the distribution the chains sample; remove integrator.clamp for mlt")
        if kwargs.get("pass_spp") is not None:
            raise InputError("mlt renders in one pass of chains (see `chains`); pass_spp does not apply to it")
        self.small_step = finite_number("mlt.small_step", small_step, "small_step")
        defines = {"MLT": True, "MLT_MAX_DIMS": self.max_dims, **step_defines(self.small_step),
                   # cl/mlt_proposals.h mlt_index: a CPU reads a vertex's dimensions from one cache line
                   "MLT_CHAIN_MAJOR": bool(queue.device.type & cl.device_type.CPU)}
        defines.update(kwargs.pop("extra_defines", None) or {})
        fraction = kwargs.pop("regenerate_fraction", None)     # None: mlt's default, below
        if fraction is not None:
            kwargs["regenerate_fraction"] = fraction
        super().__init__(queue, device_scene, extra_defines=defines, **kwargs)
        if self.chain_count is None:   # one chain per slot of the BDPT pool, within the chains' limit
            self.chain_count = min(self.pool_size, LIMITS["mlt.chains"][1])
        if fraction is None and self.chain_count <= self.pool_size:
            # One connect phase per iteration, after its last proposal has terminated: when the
            # pool holds every chain's proposal, no slot is regenerated before the chains accept,
            # so connecting the early finishers sooner frees nothing and only adds connect phases
            # (8 per iteration instead of 1 on covered_lamp 64x64; 1.65 -> 1.43 BDPT samples per mutation).
            self.regenerate_fraction = 1.0

    # --- the render: start the chains, then iterate ------------------------------------------

    def render(self, width, height, spp, seed=0, progress=None):
        film = Film(width, height)
        camera = self.scene.camera(width, height)
        pixels = width * height
        total = pixels * spp
        start = time.perf_counter()
        c = self.begin(camera, np.uint32(seed), min(self.chain_count, total))
        shown = 0
        while c.mutations < total and not self.out_of_time(start, c):
            self.iterate(c, min(c.count, total - c.mutations), MltMode.MUTATE)
            if progress is not None and c.mutations // pixels > shown:
                progress.update(c.mutations // pixels - shown)
                shown = c.mutations // pixels
        # spp as made (whole samples per pixel; fewer than asked when time_limit stopped it)
        film.add_pass(self.image(c).reshape(height, width, 3), max(1, c.mutations // pixels), nonfinite=c.nonfinite)
        self.queue.finish()
        return film

    def out_of_time(self, start, c):
        """time_limit: stop once it has passed (after at least one iteration of mutations)."""
        return self.time_limit is not None and c.mutations > 0 and time.perf_counter() - start >= self.time_limit

    def begin(self, camera, seed, count):
        """The chains' memory and their first states (`start`)."""
        ctx, n = self.queue.context, self.padded(count)
        vectors = 4 * n * self.max_dims
        c = Chains(count, cl.Buffer(ctx, cl.mem_flags.READ_WRITE, vectors),
                   cl.Buffer(ctx, cl.mem_flags.READ_WRITE, vectors),
                   cl.Buffer(ctx, cl.mem_flags.READ_WRITE, MLT_CHAIN.dtype.itemsize * n),
                   cl.Buffer(ctx, cl.mem_flags.READ_WRITE, 4 * n), self.int_buffer(count))
        cl.enqueue_fill_buffer(self.queue, c.records, np.int32(0), 0, MLT_CHAIN.dtype.itemsize * n)
        c.f_current = np.zeros(count)
        c.candidate_sum, c.weight = np.zeros(count), np.ones(count)
        c.cur_values, c.cur_pixels, c.cur_chain = np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64)
        c.splats = np.zeros((int(camera["width"] * camera["height"]), 3))
        c.large_splats = np.zeros_like(c.splats)
        self.camera, self.seed, self.last_chains = camera, seed, c
        if self.start == "naive":
            self.iterate(c, count, MltMode.START)
        elif self.start == "pool":
            first = c.iteration
            candidates = [self.iterate(c, count, MltMode.START) for _ in range(self.candidates)]
            self.start_from_pool(c, candidates, first)
        else:
            for _ in range(self.candidates):
                self.iterate(c, count, MltMode.CANDIDATE)
            if c.candidate_sum.any():
                c.weight = c.candidate_sum / c.candidate_sum.mean()
        return c

    def iterate(self, c, active, mode):
        """One iteration of the first `active` chains: mutate, evaluate, accept, splat."""
        it = MLT_ITERATION.zeros(1)[0]
        it["seed"], it["iteration"], it["chains"], it["active"] = self.seed, c.iteration, c.count, active
        it["large_step"], it["mode"] = self.large_step, int(mode)
        self.mutate(c, it)
        values, pixels, chain, f, dims = self.evaluate_proposals(c, active)
        records = self.accept(c, it, f, dims)
        self.splat(c, records, values, pixels, chain, f, mode)
        c.iteration += 1
        return values, pixels, chain, f, dims

    def start_from_pool(self, c, candidates, first):
        """start = pool: every chain's first state drawn from all the chains' candidates (large
        steps: `candidates` iterations from iteration `first`, each as returned by iterate) in
        proportion to f, by systematic resampling (one uniform offset, `count` evenly spaced
        points on the cumulative f); each chain's splat weight stays 1."""
        count = c.count
        f = np.concatenate([x[3] for x in candidates])          # entry k * count + chain
        if not f.sum() > 0:
            return                                               # no light found: keep the naive start
        rng = np.random.default_rng([int(self.seed), 0x706f6f6c])
        cdf = np.cumsum(f)
        pick = np.searchsorted(cdf, (rng.random() + np.arange(count)) / count * cdf[-1], side="right")
        pick = np.minimum(pick, len(f) - 1)
        dims = np.concatenate([x[4] for x in candidates])[pick]
        src_chain, src_iteration = pick % count, first + pick // count
        ctx, flags = self.queue.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR
        it = MLT_ITERATION.zeros(1)[0]
        it["seed"], it["chains"], it["active"] = self.seed, count, count
        self.launch(self.kernel("mlt_start_from"), count, it, c.current, c.records,
                    *(cl.Buffer(ctx, flags, hostbuf=np.ascontiguousarray(x, dtype)) for x, dtype in
                      ((src_chain, np.int32), (src_iteration, np.int32), (f[pick], np.float32), (dims, np.int32))))
        c.f_current = f[pick].astype(np.float64)
        # The chosen candidates' records become the chains' current records (a candidate picked
        # by several chains is copied to each).
        key = np.concatenate([k * count + x[2] for k, x in enumerate(candidates)])
        order = np.argsort(key, kind="stable")
        lo, hi = np.searchsorted(key[order], pick, "left"), np.searchsorted(key[order], pick, "right")
        n = hi - lo
        rows = order[np.repeat(lo - np.cumsum(n) + n, n) + np.arange(n.sum())]
        c.cur_values = np.concatenate([x[0] for x in candidates])[rows]
        c.cur_pixels = np.concatenate([x[1] for x in candidates])[rows]
        c.cur_chain = np.repeat(np.arange(count), n)

    def mutate(self, c, it):
        """mlt_mutate: every active chain writes its proposal (cl/mlt.h)."""
        self.launch(self.kernel("mlt_mutate"), int(it["active"]), it, c.current, c.proposal,
                    c.records)
        if self.count_simd:
            self.simd.add_stream_step("mutate", int(it["active"]))

    def evaluate_proposals(self, c, active):
        """The proposals as one batch of BDPT samples (sample id = chain): their records
        (values (n, 3) float64, pixels, chains) and per chain f and the dimensions used."""
        p = self.start_pass(self.camera, self.seed, c.iteration, active, chains=c.count)
        p.records, p.dims = [], np.full(active, BDPT_FIRST_SCATTER_DIM, np.int64)
        self.evaluate(p)
        if p.records:
            values, pixels, chain = (np.concatenate(x) for x in zip(*p.records))
        else:
            values, pixels, chain = np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64)
        finite = np.isfinite(values).all(1)
        if not finite.all():     # a bug to report (DroppedSamplesWarning), never a NaN in the chain
            c.nonfinite += int((~finite).sum())
            values, pixels, chain = values[finite], pixels[finite], chain[finite]
        f = np.bincount(chain, values @ np.asarray(LUMINANCE_WEIGHTS), minlength=active)
        c.overflow += int((p.dims > self.max_dims).sum())
        return values, pixels, chain, np.maximum(f, 0.0), np.minimum(p.dims, self.max_dims)

    def connect(self, p, count):
        """The parallel connect phase; its records stay with their chains (p.records) instead of
        going to the image; p.dims gets each terminated sample's used dimensions."""
        records = self.connection_records(p, count)
        if records is not None:
            values, pixels, counts_buffer = records
            counts = self.read_ints(counts_buffer, p.pool.size)
            slots = self.read_structs(BDPT_SLOT, p.pool.slots, p.pool.size)
            done = counts > 0
            ids = slots["sample_id"][done]
            p.dims[ids] = used_dims(slots["eye_vertices"][done], slots["light_vertices"][done])
            chain = np.repeat(ids, counts[done])
            ok = pixels >= 0
            p.records.append((values[ok, :3].astype(np.float64), pixels[ok], chain[ok]))
        return 0.0

    def accept(self, c, it, f, dims):
        """mlt_accept (cl/mlt.h) with the proposals' f and dimensions; returns the chain records."""
        active = int(it["active"])
        cl.enqueue_copy(self.queue, c.f_proposal, f.astype(np.float32))
        cl.enqueue_copy(self.queue, c.dims_proposal, dims.astype(np.int32))
        self.launch(self.kernel("mlt_accept"), active, it, c.current, c.proposal, c.records,
                    c.f_proposal, c.dims_proposal)
        if self.count_simd:
            self.simd.add_stream_step("accept", active)
        return self.read_structs(MLT_CHAIN, c.records, active)

    def splat(self, c, records, values, pixels, chain, f, mode):
        """Expected-value splats (MUTATE only), the large steps' f for b, and the new current records.
        With `combine`, a sample z (proposal or current) is weighted 1 / (f(z) + p b') instead of
        1 / f(z), and a large step's proposal adds b' / (f(y) + p b') to the large steps' own sum
        (Kelemen's combination; module docstring); b' is b as estimated before this iteration."""
        active = len(records)
        large = records["large_step"] != 0
        b_before = c.large_sum / max(c.large_count, 1)
        c.large_sum += float(f[large].sum())
        c.large_count += int(large.sum())
        a = records["acceptance"].astype(np.float64)
        accepted = records["accepted"] != 0
        if mode == MltMode.CANDIDATE:
            c.candidate_sum[:active] += f
        if mode == MltMode.MUTATE:
            weight = c.weight[:active]
            mix = self.large_step * b_before if self.combine else 0.0   # p b': the large steps' density, in f's units
            d_prop, d_cur = f + mix, c.f_current[:active] + mix
            w_prop = np.divide(a * weight, d_prop, out=np.zeros(active), where=d_prop > 0)
            w_cur = np.divide((1.0 - a) * weight, d_cur, out=np.zeros(active), where=d_cur > 0)
            mine = c.cur_chain < active
            v = np.concatenate([values * w_prop[chain][:, None], c.cur_values[mine] * w_cur[c.cur_chain[mine]][:, None]])
            c.splats += per_pixel_sums(v, np.concatenate([pixels, c.cur_pixels[mine]]), len(c.splats))
            if self.combine:
                w_large = np.divide(b_before * large, d_prop, out=np.zeros(active), where=d_prop > 0)
                ours = large[chain]
                c.large_splats += per_pixel_sums(values[ours] * w_large[chain[ours]][:, None], pixels[ours],
                                                 len(c.splats))
            c.mutations += active
            c.accepted += int(accepted.sum())
        replaced = np.zeros(c.count, bool)
        replaced[:active] = accepted
        keep, new = ~replaced[c.cur_chain], replaced[chain]
        c.cur_values = np.concatenate([c.cur_values[keep], values[new]])
        c.cur_pixels = np.concatenate([c.cur_pixels[keep], pixels[new]])
        c.cur_chain = np.concatenate([c.cur_chain[keep], chain[new]])
        c.f_current[:active][accepted] = f[accepted]

    def image(self, c):
        """P / M * (b * the Metropolis splats + the large steps' splats): the estimator of the module docstring."""
        b = c.large_sum / max(c.large_count, 1)
        return (c.splats * b + c.large_splats) * (len(c.splats) / max(c.mutations, 1))

    # --- measuring --------------------------------------------------------------------------

    def sampler_args(self):
        return (self.last_chains.proposal,)

    def extra_stats(self):
        stats = super().extra_stats()
        c = self.last_chains
        stats["mlt"] = {"chains": c.count, "start": self.start, "large_step": self.large_step, "combine": self.combine,
                        "mutations": c.mutations, "mutations_per_chain": c.mutations / c.count,
                        "acceptance_rate": c.accepted / max(c.mutations, 1),
                        "b": c.large_sum / max(c.large_count, 1), "large_steps": c.large_count,
                        "max_dims": self.max_dims, "overflow_proposals": c.overflow}
        return stats
