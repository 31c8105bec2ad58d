"""Metropolis light transport: many independent primary-sample-space chains (Kelemen et al. 2002)
over the bidirectional estimator, as in the talk's slides "Metropolis Light Transport" and
"Startup Bias". Kernels: cl/mlt.cl (cl/mlt.h: mutation and acceptance; cl/mlt_contribution.h:
each proposal's f, summed on the device from its records; cl/mlt_splat.h: the splats, the
current states' records and b; the BDPT kernels of cl/bdpt_parallel_connect.cl built with
-DMLT=1 read their uniforms from the chains' vectors).

One iteration, read like the slide, every step of it on the device:
    mutate every chain (large step with probability `large_step`, else a small step);
    evaluate all proposals as one batch of BDPT samples (BDPT's evaluator, bdpt_evaluator.py:
        compacted walks, parallel connect; the records go to the chains, not to an image,
        and each proposal's f is summed from them);
    accept or reject per chain;
    splat the proposal with weight a and the current state with weight 1 - a.
While the chains iterate the host waits for nothing: it reads one count per iteration, behind the
kernels and looked at iterations later (how many records the current states keep: mlt_chains.py
Chains.next_store), and the films, b and the tallies once at the end (for start = pool, also the
candidates' f and their records' counts once, to pick the starts and size their store).

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
with their first mutations. N is `candidates`, by default such that the pool holds POOL_CANDIDATES
(default_candidates: a larger pool removes no bias the tests can see, and every candidate costs a
BDPT sample). The candidates are one batch of BDPT samples, not `candidates` iterations of the
chains (evaluate_candidates: the pool regenerates like a BDPT pass, and no iteration's own kernels
run), and each keeps its f, dimensions and records on the device, so a chain starts at its
picked candidate without evaluating it again (start_from_pool).

Splats are summed on the device, into two record films (toolkit/opencl/record_film.py: exact
128-bit fixed point per pixel and channel, so the order of the additions changes no bit; no float
atomics): the Metropolis splats, scaled by the final b when the image is made, and with `combine`
the large steps' own. A splat is a record (value, pixel) with its weight in .w (cl/mlt_splat.h).
Each proposal's records go to a proposal store on the device, and each chain's current state keeps
its records in a current store, rebuilt after each acceptance from the accepted proposals' records
and the kept states'; the host bounds the stores' sizes from the records proposed and a read of the
current store's size queued LAG iterations before (never waited for while the device is behind).
Each proposal's f is the float32 sum of its records' luminance on the device, in the order the
connect phase wrote them (cl/mlt_contribution.h: the same bits every run). b's sum is exact too:
each large step's f, in fixed point, added with integer atomics to one 128-bit sum
(cl/mlt_splat.h); b before each iteration, for the combination's weights, is computed from it on
the device. The records dropped for a non-finite value, the proposals past max_dims, the accepted
mutations and the large steps are counted there too, and read at the end, with b's sum.

Options (keyword arguments of toolkit.render(..., options=...)):

| option | default | meaning |
| --- | --- | --- |
| `chains` | the device's (`devices` shows it; toolkit/opencl/work_sizes.py mlt_chains): a GPU's resident work-items, CPU_CHAINS_PER_UNIT per core on a CPU: enough to fill the device, as every chain more adds startup bias | independent chains; 1 .. 2^18 (`mlt.chains`), at most the mutations of the render |
| `large_step` | 0.3 | probability of a large step (every dimension fresh) |
| `small_step` | 1/16 | the largest size of a small step, Kelemen's s2 (the smallest, s1, is s2 / 16); see SMALL_STEP |
| `start` | `pool` | `naive`: each chain starts at one large step (the talk; biased at first). `resample`: at one of its own `candidates` large steps, chosen in proportion to f, and weighted. `pool`: at one of all chains' candidates, chosen in proportion to f, weight 1. `pool` is the default because the default chain count fills the device, whatever the image: at 256 mutations per pixel on this 2-core CPU's 2,048 chains, naive chains were still biased on cornell_spheres (32x32, 11 seeds: worst region |z| 19.7, p 2e-9 against the Bonferroni threshold 5e-5), pool and resample were not (3.8 and 2.8), and pool passed on every bundled scene down to 8 mutations per chain (results/issue48_mlt_start.md), with 16 candidates per chain; with a GPU's chain count, 1 mutation per chain and the default candidates (16,384 chains x 2), it passes too on cornell_spheres (worst |z| 5.3, naive: 162; tests/test_mlt.py). At equal time (30 s, 32x32, two-core CPU) pool's RMSE was 0.0064 against naive's 0.0066 on covered_lamp and 0.0091 against 0.019 on cornell_spheres, where naive chains are still biased; on cornell_box, where they are not, naive was ahead (0.0060 against 0.0072). At 10 s (3 repetitions, results/issue10_mlt.md) pool removes naive's detected bias on covered_lamp and cornell_spheres but adds variance (chains that start at the same bright candidate): RMSE 0.113 against 0.108 (covered_lamp), 0.072 against 0.128 (cornell_spheres). `naive` is the talk's start, one iteration long: toolkit/measure/mlt_bias.py and tutorial 06 measure its bias |
| `candidates` | 16 up to 2,048 chains, then fewer: POOL_CANDIDATES (32,768) / chains, rounded up, at least 1 (`default_candidates`: 4,096 chains draw 8 each, a GPU's 262,144 draw 1) | large steps per chain for `start = resample` or `pool` (`mlt.candidates`). The default keeps the pool at the size validated on every bundled scene (results/issue48_mlt_start.md), whose bias, O(1 / (chains x candidates)), is far below the tests' resolution, and no larger: every candidate costs a BDPT sample, and 16 each on a GPU's chains cost four times the mutations of a 16-spp render at 256x256. The same rule for `resample`: its weights' ratio-estimator bias and variance come from all chains' candidates together too. The stats' `mlt.candidates` is the number used |
| `max_dims` | 128 | primary-sample dimensions a chain stores: 8 + 8 per vertex of the longer subpath after the first, so 128 holds subpaths of 16 vertices (DEFAULT_MAX_DIMS) (`mlt.max_dims`). A path that reads more gets fresh random numbers for the extra dimensions at every iteration (cl/mlt_proposals.h): still correct, and counted (`overflow_proposals`) |
| `combine` | true | Kelemen's combination: the large steps also splat as BDPT samples, joined with the Metropolis states by the balance heuristic (above) |
| `time_limit` | none | seconds: stop after the iteration that passes it (the image holds the mutations made so far) |
| BDPT options | | `pool_size` (the device's, as for bdpt_parallel_connect: with the default chains an iteration is one pool-full; a pool of a quarter of the chains, which regenerates like a BDPT pass, measured no faster on covered_lamp 64x64), `regenerate_fraction` (default 1 where the pool holds every chain: one connect phase per iteration; else 0.6 as for BDPT), `coalesced_scatter` as for bdpt_parallel_connect |

spp means mutations: a render of spp samples per pixel makes spp x pixels mutations in all
(iterations of `chains` mutations; the last may use fewer chains), fewer if `time_limit` stops it. The start's samples come
on top. The image has no standard error of its own (one pass; MLT samples are correlated):
compare independent runs (seeds), as tests/test_mlt.py and toolkit/measure/mlt_bias.py do.
"""
import dataclasses
import time

import numpy as np
import pyopencl as cl

from toolkit.core.sample_dims import used_dims
from toolkit.core.layout import FILM_ACCUMULATOR, MLT_CHAIN, MLT_ITERATION, MltMode, MltTally
from toolkit.core.validate import InputError, finite_number, whole_number
from toolkit.opencl.work_sizes import device_work_sizes
from toolkit.techniques.base import pixel_count
from toolkit.opencl.record_film import RecordFilm, film_word_bits, unit_exponent_for
from toolkit.techniques.bdpt_evaluator import REGENERATE_FRACTION, BdptEvaluator, BdptPoolTechnique
from toolkit.techniques.bdpt_parallel_connect import ParallelConnect
from toolkit.techniques.mlt_chains import Chains, ProposalSink, SampleBatch, systematic_picks

STARTS = ("naive", "resample", "pool")

# The candidates the start draws in all, chains x candidates, by default: the pool validated
# against every bundled reference (results/issue48_mlt_start.md: 2,048 chains x 16). The start's
# bias is O(1 / pool size), already far below the tests' resolution there, while every candidate
# costs a BDPT sample: a GPU's 262,144 chains x 16 would be 4.2 M of them, four times the
# mutations of a 16-spp render at 256x256 (results/issue48_bench_ab.md).
POOL_CANDIDATES = 32768
MOST_CANDIDATES = 16    # per chain, by default: the validated 16 (fewer chains draw no more each)


def default_candidates(chains):
    """Large steps per chain for start = pool or resample when `candidates` is not given: enough
    for POOL_CANDIDATES in all, at least 1 and at most MOST_CANDIDATES each (2,048 chains: 16;
    262,144: 1)."""
    return min(MOST_CANDIDATES, max(1, -(-POOL_CANDIDATES // chains)))    # -(-a // b): a / b rounded up


# Subpaths whose every dimension a chain stores by default: 16 vertices, 128 dimensions
# (toolkit/core/sample_dims.py used_dims); longer paths read fresh numbers past them.
DEFAULT_MAX_DIMS = int(used_dims(16, 16))

SMALL_STEP = 1 / 16
# The largest small step, Kelemen's s2 (his paper: 1/64, with s1 = 1/1024). On covered_lamp,
# 32x32, 4,096 chains, 64 mutations each, pool start, 6 runs, the relative squared error of one
# run was 0.0216 with s2 = 1/64 and 0.0136 with 1/16 (1/32: 0.0167, 1/8: 0.0161 at large_step 0.1):
# paths through the slit tolerate larger moves than the 1/64 that Kelemen tuned for.


def step_defines(small_step):
    """The small step's sizes for cl/mlt.h: s2 = small_step, s1 = s2 / 16 (Kelemen's ratio)."""
    return {"MLT_S2": float(small_step), "MLT_S1": float(small_step) / 16}


class Mlt(BdptPoolTechnique):
    """Metropolis chains whose proposals BDPT's evaluator (bdpt_evaluator.py) evaluates with the
    parallel connect phase; the records go to the chains (ProposalSink), not to an image."""
    name = "mlt"
    source = "mlt.cl"
    family = "mlt"

    def __init__(self, queue, device_scene, chains=None, large_step=0.3, start="pool", candidates=None,
                 max_dims=DEFAULT_MAX_DIMS, combine=True, time_limit=None, small_step=SMALL_STEP, pool_size=None,
                 regenerate_fraction=None, coalesced_scatter=True, **kwargs):
        self.check_options(device_scene.scene, chains, large_step, start, candidates, max_dims, combine,
                           time_limit, small_step, kwargs)
        defines = {"MLT": True, "MLT_MAX_DIMS": self.max_dims, **step_defines(self.small_step),
                   # cl/mlt_proposals.h mlt_index: a CPU reads a vertex's dimensions from one cache line
                   "MLT_CHAIN_MAJOR": bool(queue.device.type & cl.device_type.CPU),
                   "FILM_WORD_BITS": film_word_bits(queue.device)}   # b's exact sum (cl/mlt_splat.h)
        super().__init__(queue, device_scene, defines, pool_size, coalesced_scatter, **kwargs)
        if self.chain_count is None:   # enough to fill the device, no more (toolkit/opencl/work_sizes.py mlt_chains)
            self.chain_count = min(device_work_sizes(queue.device, self.max_vertices).chains, self.pool_size)
        if regenerate_fraction is None:
            # One connect phase per iteration, after its last proposal has terminated: when the
            # pool holds every chain's proposal, no slot is regenerated before the chains accept,
            # so connecting the early finishers sooner frees nothing and only adds connect phases
            # (8 per iteration instead of 1 on covered_lamp 64x64; 1.65 -> 1.43 BDPT samples per mutation).
            # Else BDPT's 0.6.
            regenerate_fraction = 1.0 if self.chain_count <= self.pool_size else REGENERATE_FRACTION
        self.bdpt = BdptEvaluator(self.bdpt_context, ParallelConnect(self.bdpt_context),
                                  self.pool_size, regenerate_fraction, self.max_vertices)
        self.last_chains = None   # the chains of the last render, for its stats
        self.total = 0            # the render's mutations in all (begin_render)
        self.started = None       # when its chains started (perf_counter), for time_limit

    def check_options(self, scene, chains, large_step, start, candidates, max_dims, combine, time_limit,
                      small_step, kwargs):
        """Every option checked (InputError) and kept, before the build."""
        self.chain_count = whole_number("mlt.chains", chains, "chains") if chains is not None else None
        self.large_step = finite_number("mlt.large_step", large_step, "large_step")
        if start not in STARTS:
            raise InputError(f"start must be one of {', '.join(STARTS)}, got {start!r}")
        self.start = start
        # None: default_candidates of the chains a render starts (candidates_for)
        self.candidates = None if candidates is None else whole_number("mlt.candidates", candidates, "candidates")
        self.max_dims = whole_number("mlt.max_dims", max_dims, "max_dims")
        if combine not in (True, False):
            raise InputError(f"combine must be true or false, got {combine!r}")
        self.combine = bool(combine)
        self.time_limit = None if time_limit is None else finite_number("mlt.time_limit", time_limit, "time_limit")
        if scene.clamp is not None:
            raise InputError("mlt does not clamp (scene integrator.clamp is set): every Metropolis splat already has "
                             "the same brightness b / M, so there are no fireflies to cap, and a capped f would only "
                             "change the distribution the chains sample; remove integrator.clamp for mlt")
        if kwargs.get("pass_spp") is not None:
            raise InputError("mlt renders in one pass of chains (see `chains`); pass_spp does not apply to it")
        self.small_step = finite_number("mlt.small_step", small_step, "small_step")

    def candidates_for(self, chains):
        """Large steps per chain that a start of `chains` chains draws: the option, else the default."""
        return default_candidates(chains) if self.candidates is None else self.candidates

    # --- the render: start the chains, then iterate ------------------------------------------
    # One render is one set of chains: its passes are not independent images (Technique.render
    # adds each pass to the film) but stretches of the same chains, one mutation per pixel each.
    # The film gets the chains' image once, at the end.

    def begin_render(self, camera, seed, spp):
        self.total = pixel_count(camera) * spp          # mutations in all
        chains = min(self.chain_count, self.total)
        if self.total + self.candidates_for(chains) * chains >= 2 ** 31:
            raise InputError(f"mlt counts its mutations and large steps in 32-bit integers on the device: "
                             f"{self.total:,} mutations are too many; render fewer pixels or samples per pixel")
        self.started = time.perf_counter()
        self.begin(camera, seed, chains)

    def spp_per_pass(self, pixels, spp):
        return 1    # a pass: the iterations that make one more mutation per pixel (progress, time_limit)

    def run_pass(self, film, camera, seed, sample_base, spp):
        """Iterate the chains until they have made (sample_base + spp) mutations per pixel; an
        iteration does not stop at a pass's end (every chain is active until the last)."""
        c, end = self.last_chains, (sample_base + spp) * pixel_count(camera)
        while c.mutations < min(end, self.total) and not self.out_of_time(self.started, c):
            self.iterate(c, min(c.count, self.total - c.mutations), MltMode.MUTATE)

    def end_render(self, film):
        c, pixels = self.last_chains, film.width * film.height
        # spp as made (whole samples per pixel; fewer than asked when time_limit stopped it)
        image = self.image(c)      # reads the films, b and the tallies: the render's only reads of its chains
        film.add_pass(image.reshape(film.height, film.width, 3), max(1, c.mutations // pixels), nonfinite=c.nonfinite)
        self.queue.finish()

    def out_of_time(self, start, c):
        """time_limit: stop once it has passed (after at least one iteration of mutations)."""
        return self.time_limit is not None and c.mutations > 0 and time.perf_counter() - start >= self.time_limit

    def begin(self, camera, seed, count):
        """The chains' memory and their first states (`start`)."""
        ctx, n, mem = self.queue.context, self.memory.padded(count), self.memory
        candidates = self.candidates_for(count) if self.start != "naive" else 0
        vectors, pixels = 4 * n * self.max_dims, pixel_count(camera)
        unit = unit_exponent_for(self.scene.scene.emission_of.max())
        films = tuple(RecordFilm(self.queue, pixels, self.local_size, self.sources.toolkit_only(), unit_exponent=e)
                      for e in (0, unit))   # the Metropolis splats are h / f, about 1; the large steps' in f's units
        buffer = lambda size: cl.Buffer(ctx, cl.mem_flags.READ_WRITE, size)
        c = Chains(count, seed, camera, mem, current=buffer(vectors), proposal=buffer(vectors),
                   records=buffer(MLT_CHAIN.dtype.itemsize * n), tallies=mem.int_buffer(len(MltTally), fill=0),
                   weight=buffer(4 * n), splat_weights=buffer(16 * n),
                   b_sum=mem.int_buffer(FILM_ACCUMULATOR.dtype.itemsize // 4, fill=0), b_estimate=buffer(4),
                   films=films, pixels=pixels, candidates=candidates)
        cl.enqueue_fill_buffer(self.queue, c.records, np.int32(0), 0, MLT_CHAIN.dtype.itemsize * n)
        cl.enqueue_fill_buffer(self.queue, c.weight, np.float32(1), 0, 4 * n)
        cl.enqueue_fill_buffer(self.queue, c.b_estimate, np.float32(0), 0, 4)
        self.last_chains = c
        if self.start == "naive":
            self.iterate(c, count, MltMode.START)
        elif self.start == "pool":
            first = c.iteration
            self.start_from_pool(c, self.evaluate_candidates(c, candidates), first)
        else:
            for _ in range(candidates):
                self.iterate(c, count, MltMode.CANDIDATE)
            self.kernels.launch("mlt_resample_weights", count, it=self.iteration_args(c, count, MltMode.CANDIDATE),
                                chains=c.records, b_sum=c.b_sum, weight=c.weight)
        return c

    def iteration_args(self, c, active, mode):
        """The MltIteration record of the chains' next iteration."""
        it = MLT_ITERATION.zeros(1)[0]
        it["seed"], it["iteration"], it["chains"], it["active"] = c.seed, c.iteration, c.count, active
        it["large_step"], it["mode"] = self.large_step, int(mode)
        it["unit_exponent"] = c.films[1].unit_exponent   # b's sum and the films' fixed point (one scale)
        return it

    def iterate(self, c, active, mode):
        """One iteration of the first `active` chains, as on the slide, all of it on the device."""
        it = self.iteration_args(c, active, mode)
        self.mutate(c, it)                               # every chain proposes (large or small step)
        proposed = self.evaluate_proposals(c, active)    # all proposals as one batch of BDPT samples
        self.accept(c, it)                               # accept or reject per chain
        self.splat(c, it, proposed)                      # proposal with weight a, current state with 1 - a
        c.iteration += 1
        if mode == MltMode.MUTATE:
            c.mutations += active

    def evaluate_candidates(self, c, per_chain):
        """start = pool: the chains' `per_chain` candidates each, large steps, as one batch of BDPT
        samples (candidate k is chain k % count's large step of iteration c.iteration + k // count:
        cl/bdpt_walk.h bdpt_sampler_mlt), not `per_chain` iterations of the chains: the pool
        regenerates like a BDPT pass and the iterations' own kernels are not run. Returns the
        SampleBatch of their f, dimensions and records; their f goes into b on the device."""
        n = c.count * per_chain
        self.mutate(c, self.iteration_args(c, c.count, MltMode.START))   # every dimension of every proposal fresh
        batch = SampleBatch(self.memory, n)
        evaluator = dataclasses.replace(self.bdpt, regenerate_fraction=REGENERATE_FRACTION)
        p = evaluator.start_pass(c.camera, c.seed, c.iteration, n, sampler_args={"mlt_primary": c.proposal},
                                 vector_stride=c.count)
        sink = ProposalSink(self.kernels, batch, c.tallies, n, p.pool.size)
        evaluator.evaluate(p, sink)
        sink.records()
        unit_exponent = np.int32(c.films[1].unit_exponent)   # b's units: the large steps' film's
        self.kernels.launch("mlt_candidates_into_b", n, candidates=np.int32(n), unit_exponent=unit_exponent,
                            f_candidate=batch.f, b_sum=c.b_sum, tallies=c.tallies)
        self.kernels.launch("mlt_estimate_first_b", 1, b_sum=c.b_sum, unit_exponent=unit_exponent,
                            tallies=c.tallies, b_estimate=c.b_estimate)
        c.iteration += per_chain
        return batch

    def start_from_pool(self, c, candidates, first):
        """start = pool: every chain's first state drawn from all the chains' candidates (their
        SampleBatch, from iteration `first`) in proportion to f, by systematic resampling; each
        starts there with the candidate's f, dimensions and records (mlt_start_from), not evaluated
        again. Each chain's splat weight stays 1. The host reads the candidates' f and their
        records' spans once: f for the picks, the spans for the current store's exact size."""
        count, n = c.count, candidates.samples
        f = np.empty(n, np.float32)
        cl.enqueue_copy(self.queue, f, candidates.f)
        f = f.astype(np.float64)
        if not f.sum() > 0:                                      # no light found: a naive start
            self.iterate(c, count, MltMode.START)
            return
        pick = systematic_picks(f, count, np.random.default_rng([int(c.seed), 0x706f6f6c]))
        spans = self.memory.read_ints(candidates.store.span, 2 * n).reshape(n, 2)
        store = c.next_store(int(spans[pick, 1].sum()))
        it = self.iteration_args(c, count, MltMode.START)
        it["iteration"], it["store_capacity"] = first, store.capacity
        upload = cl.Buffer(self.queue.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                           hostbuf=np.ascontiguousarray(pick, np.int32))
        s = candidates.store
        self.kernels.launch("mlt_start_from", count, it=it, pick=upload,
                            f_candidate=candidates.f, dims_candidate=candidates.dims, candidate_span=s.span,
                            candidate_value=s.value, candidate_pixel=s.pixel, current=c.current, chains=c.records,
                            next_span=store.span, next_value=store.value, next_pixel=store.pixel,
                            next_chain=store.chain, next_total=store.total, tallies=c.tallies)
        c.kept(store)

    # --- the stages of an iteration, one kernel (or one BDPT evaluation) each ------------------

    def mutate(self, c, it):
        """mlt_mutate: every active chain writes its proposal (cl/mlt.h)."""
        self.kernels.launch("mlt_mutate", int(it["active"]), it=it, current=c.current, proposal=c.proposal,
                            chains=c.records)
        if self.count_simd:
            self.recorder.before_step("mutate", int(it["active"]))

    def evaluate_proposals(self, c, active):
        """The proposals as one batch of BDPT samples (sample id = chain, random numbers from the
        proposals' vectors): their f and dimensions summed on the device, their records kept there
        with their chains (ProposalSink). Returns how many records they have."""
        p = self.bdpt.start_pass(c.camera, c.seed, c.iteration, active, sampler_args={"mlt_primary": c.proposal},
                                 vector_stride=c.count)
        sink = ProposalSink(self.kernels, c.proposed, c.tallies, active, p.pool.size)
        self.bdpt.evaluate(p, sink)
        return sink.records()

    def accept(self, c, it):
        """mlt_accept_and_weigh (cl/mlt_splat.h): each chain's splat weights from a, before its current
        state changes, and the large steps' f into b; then its acceptance (cl/mlt.h mlt_accept_chain)
        with the proposals' f and dimensions (on the device since the connect phases). One launch."""
        active = int(it["active"])
        self.kernels.launch("mlt_accept_and_weigh", active, it=it, current=c.current, proposal=c.proposal,
                            chains=c.records, f_proposal=c.proposed.f, dims_proposal=c.proposed.dims,
                            weight=c.weight, b_estimate=c.b_estimate, combine=np.int32(self.combine),
                            splat_weights=c.splat_weights,
                            b_sum=c.b_sum, tallies=c.tallies)
        if self.count_simd:
            self.recorder.before_step("accept", active)

    def splat(self, c, it, proposed):
        """The expected-value splats into the films (MUTATE only): the proposals' records with
        weight a, the current states' with 1 - a and, with `combine`, the large steps' own; then
        the accepted proposals' records become the current states' (mlt_keep_records, which also
        estimates b for the next iteration). All on the device (cl/mlt_splat.h)."""
        active, (metropolis, large) = int(it["active"]), c.films
        current, proposals = c.stores[0], c.proposed.store
        if it["mode"] == MltMode.MUTATE:
            for store, count, component, film in ((proposals, proposed, 0, metropolis),
                                                  (current, min(c.bound, current.capacity), 1, metropolis),
                                                  (proposals, proposed if self.combine else 0, 2, large)):
                if count:
                    self.kernels.launch("mlt_weigh_records", count, capacity=np.int32(count), total=store.total,
                                        active=np.int32(active), component=np.int32(component),
                                        splat_weights=c.splat_weights, record_chain=store.chain,
                                        record_value=store.value, record_pixel=store.pixel)
                    film.add(store.value, store.pixel, count, weighted=True)
        nxt = c.next_store(proposed)
        it["store_capacity"] = nxt.capacity
        self.kernels.launch("mlt_keep_records", c.count, it=it, chains=c.records, proposal_span=proposals.span,
                            proposal_value=proposals.value, proposal_pixel=proposals.pixel,
                            current_span=current.span, current_value=current.value, current_pixel=current.pixel,
                            next_span=nxt.span, next_value=nxt.value, next_pixel=nxt.pixel, next_chain=nxt.chain,
                            next_total=nxt.total, tallies=c.tallies, b_sum=c.b_sum, b_estimate=c.b_estimate)
        c.kept(nxt)

    def image(self, c):
        """P / M * (b * the Metropolis splats + the large steps' splats): the estimator of the module
        docstring. Reads the films (each resolved into the host's float64 sums, after which the
        device's start again at zero), b and the tallies."""
        for film, total in zip(c.films, (c.splats, c.large_splats)):
            sums, read = film.resolve()
            read.wait()
            total += sums[:, :3]
            c.film_dropped += int(sums[:, 3].sum())
        c.read_tallies()
        return (c.splats * c.b + c.large_splats) * (len(c.splats) / max(c.mutations, 1))

    # --- measuring --------------------------------------------------------------------------

    def extra_stats(self):
        c = self.last_chains
        return {**super().extra_stats(),
                "mlt": {"chains": c.count, "start": self.start, "candidates": c.candidates,
                        "large_step": self.large_step, "combine": self.combine,
                        "mutations": c.mutations, "mutations_per_chain": c.mutations / c.count,
                        "acceptance_rate": c.accepted / max(c.mutations, 1), "b": c.b, "large_steps": c.large_count,
                        "max_dims": self.max_dims, "overflow_proposals": c.overflow}}
