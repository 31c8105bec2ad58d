"""The host's side of mlt's chains (toolkit/techniques/mlt.py): their device memory (every chain's
state, the records that belong to chains, the films and b) and the sink that keeps BDPT's
connection records with their chains, on the device."""
from dataclasses import dataclass, field

import numpy as np
import pyopencl as cl

from toolkit.core.layout import FILM_FRACTION_BITS, MltTally
from toolkit.core.sample_dims import BDPT_FIRST_SCATTER_DIM   # the dimension table the kernels read
from toolkit.techniques.pass_end import LAG


class RecordStore:
    """Connection records that belong to chains, on the device (cl/mlt_splat.h): per record its
    value (float4; .w is its splat weight, set before each splat), pixel (-1: none) and chain; per
    chain its span (int2: where its records start, how many there are); and `total`, the records in the store
    (an int on the device). `capacity`: the records it can hold."""

    def __init__(self, memory, chains, capacity):
        ctx = memory.queue.context
        self.capacity = capacity
        self.value = cl.Buffer(ctx, cl.mem_flags.READ_WRITE, 16 * max(1, capacity))
        # -1: no record (an entry reserved but never written reads as none)
        self.pixel, self.chain = memory.int_buffer(capacity, fill=-1), memory.int_buffer(capacity, fill=-1)
        self.span = memory.int_buffer(2 * chains, fill=0)
        self.total = memory.int_buffer(1, fill=0)


def store_capacity(n):
    """Room for at least n records: a power of two (a store grows seldom)."""
    return 1 << max(12, (int(n) - 1).bit_length())


class SampleBatch:
    """Samples evaluated on the device, sample id = entry: each one's f (float), used dimensions
    (int) and records (a RecordStore with a span per sample). The chains' proposals are one (sample
    = chain); start = pool's candidates another (sample = candidate)."""

    def __init__(self, memory, samples):
        self.memory, self.samples = memory, samples
        self.f = cl.Buffer(memory.queue.context, cl.mem_flags.READ_WRITE, 4 * memory.padded(samples))
        self.dims = memory.int_buffer(samples)
        self.store = RecordStore(memory, samples, store_capacity(1))

    def store_for(self, n, kept):
        """The store, grown to hold n records if needed (its first `kept` copied over)."""
        if n > self.store.capacity:
            old, self.store = self.store, RecordStore(self.memory, self.samples, store_capacity(n))
            q = self.memory.queue
            for name, size in (("value", 16), ("pixel", 4), ("chain", 4)):
                if kept:
                    cl.enqueue_copy(q, getattr(self.store, name), getattr(old, name), byte_count=size * kept)
            cl.enqueue_copy(q, self.store.span, old.span, byte_count=8 * self.samples)
        return self.store


class ProposalSink:
    """Where BDPT's connect phases put the records of a batch of samples (SampleBatch: the chains'
    proposals, or the start's candidates). On the device, mlt_proposal_sums (cl/mlt_contribution.h)
    sums each sample's contribution f and used dimensions into the batch's f and dims, and copies
    its records to the batch's store, one connect phase after another: nothing is read back."""

    def __init__(self, kernels, batch, tallies, samples, pool):
        self.kernels, self.batch, self.tallies, self.pool = kernels, batch, tallies, pool
        self.total = 0                                     # records stored: the connect phases' so far
        queue = kernels.queue
        # a sample that never connects has f = 0, used the start's dimensions and has no records
        cl.enqueue_fill_buffer(queue, batch.f, np.float32(0), 0, 4 * samples)
        cl.enqueue_fill_buffer(queue, batch.dims, np.int32(BDPT_FIRST_SCATTER_DIM), 0, 4 * samples)
        cl.enqueue_fill_buffer(queue, batch.store.span, np.int32(0), 0, 8 * samples)

    def add(self, connections):
        """The records of one connect phase (on the device: Connections' buffers)."""
        if connections.count == 0:
            return
        b = self.batch
        store = b.store_for(self.total + connections.count, self.total)
        # a record the phase did not write (none today: count is exact) splats nothing
        cl.enqueue_fill_buffer(self.kernels.queue, store.pixel, np.int32(-1), 4 * self.total, 4 * connections.count)
        self.kernels.launch("mlt_proposal_sums", self.pool, pool=np.int32(self.pool), slots=connections.slot_buffer,
                            counts=connections.count_buffer, firsts=connections.first_buffer,
                            record_value=connections.value_buffer, record_pixel=connections.pixel_buffer,
                            f_proposal=b.f, dims_proposal=b.dims, tallies=self.tallies,
                            store_base=np.int32(self.total), store_value=store.value, store_pixel=store.pixel,
                            store_chain=store.chain, proposal_span=store.span)
        self.total += connections.count

    def records(self):
        """The records stored (their total, also on the device for the kernels that read it)."""
        cl.enqueue_fill_buffer(self.kernels.queue, self.batch.store.total, np.int32(self.total), 0, 4)
        return self.total


@dataclass
class Chains:
    """The chains' device memory, all of their state: the host keeps only counts it knows without
    reading (iterations, mutations) and what bounds the stores' sizes."""
    count: int
    seed: np.uint32          # the render's seed
    camera: np.void          # Camera record
    memory: object           # the technique's DeviceMemory
    current: cl.Buffer       # float[max_dims][count]: the current states' primary-sample vectors
    proposal: cl.Buffer      # float[max_dims][count]: this iteration's proposals
    records: cl.Buffer       # MltChain[count]
    tallies: cl.Buffer       # int[len(MltTally)]: the render's counts kept on the device, read at its end
    weight: cl.Buffer        # float[count]: each chain's splat weight, 1 or w_c / mean(w) (start = resample)
    splat_weights: cl.Buffer  # float4[count]: this iteration's weights (cl/mlt_splat.h mlt_chain_splat_weights)
    b_sum: cl.Buffer         # FilmAccumulator[1]: the exact sum of the large steps' f (red channel)
    b_estimate: cl.Buffer    # float[1]: b before this iteration
    films: tuple             # RecordFilms of the Metropolis splats (times b at the end) and the large steps' own
    pixels: int              # of the image the chains splat into
    candidates: int = 0      # large steps per chain of the start (start = pool or resample; naive: 0)
    iteration: int = 0
    mutations: int = 0
    overflow: int = 0        # proposals that read more than max_dims dimensions (read_tallies)
    nonfinite: int = 0       # records dropped for a non-finite value (read_tallies, and the films)
    accepted: int = 0        # accepted mutations (read_tallies)
    large_count: int = 0     # large steps in b (read_tallies)
    b_total: float = 0.0     # their sum of f (read_tallies)
    film_dropped: int = 0    # splats the films left out (not finite, or beyond FILM_RECORD_LIMIT): a bug
    proposed: SampleBatch = field(init=False)   # this iteration's proposals: f, dimensions, records (ProposalSink)
    stores: list = field(init=False)            # the current states' records, and the next ones' (swapped)
    bound: int = 0           # at least the records of the current store (next_store)
    rebuilds: int = 0        # current stores made so far (a picked start's iteration makes one too)
    added: list = field(init=False)             # (rebuild, records proposed) since the last total read
    pending: list = field(init=False)           # (rebuild, PendingRead of that current store's total)
    splats: np.ndarray = field(init=False)        # (pixels, 3) float64: the Metropolis splats resolved so far
    large_splats: np.ndarray = field(init=False)  # (pixels, 3) float64: the large steps' own, likewise

    def __post_init__(self):
        self.proposed = SampleBatch(self.memory, self.count)
        self.stores = [RecordStore(self.memory, self.count, store_capacity(1)) for _ in range(2)]
        self.added, self.pending = [], []
        self.splats, self.large_splats = np.zeros((self.pixels, 3)), np.zeros((self.pixels, 3))

    def next_store(self, proposed):
        """The store the next current states go to: room for the current ones and this iteration's
        `proposed` records (every chain keeps one or the other), its total at zero. The bound on the
        current store's records comes from a read of its total queued LAG iterations ago (never waited
        for before the device is past it), plus every record proposed since."""
        while self.pending and (len(self.pending) > LAG or self.pending[0][1].event.command_execution_status
                                == cl.command_execution_status.COMPLETE):
            rebuild, read = self.pending.pop(0)
            self.added = [(k, n) for k, n in self.added if k > rebuild]
            self.bound = min(self.bound, int(read.result()) + sum(n for _, n in self.added))
        self.bound += proposed
        self.added.append((self.rebuilds, proposed))
        store = self.stores[1]
        if store.capacity < self.bound:
            store = self.stores[1] = RecordStore(self.memory, self.count, store_capacity(self.bound))
        # its old records past the new total are left: mlt_weigh_records gives them pixel -1 (no fill)
        self.memory.fill_ints(store.total, 0)
        return store

    def kept(self, store):
        """The next store is now the current one; its total is read behind the kernels (next_store)."""
        self.stores = [store, self.stores[0]]
        self.pending.append((self.rebuilds, self.memory.read_later(store.total, np.int32)))
        self.rebuilds += 1

    def read_tallies(self):
        """The counts the kernels kept (MltTally) and b's sum, read once: at the end of the render."""
        tallies = self.memory.read_ints(self.tallies, len(MltTally))
        self.nonfinite, self.overflow = int(tallies[MltTally.NONFINITE]), int(tallies[MltTally.OVERFLOW])
        self.accepted, self.large_count = int(tallies[MltTally.ACCEPTED]), int(tallies[MltTally.LARGE_STEPS])
        if tallies[MltTally.STORE_OVERFLOW]:
            raise RuntimeError(f"mlt: {tallies[MltTally.STORE_OVERFLOW]} records found no room in the current "
                               f"states' store (Chains.next_store's bound is wrong): a bug, please report it")
        words = np.empty(4, np.uint32)
        cl.enqueue_copy(self.memory.queue, words, self.b_sum)
        self.b_total = exact_fixed_point(words, self.films[1].unit_exponent)
        self.nonfinite += self.film_dropped

    @property
    def b(self):
        """The estimate of b: the mean f of the large steps (as of read_tallies)."""
        return self.b_total / max(self.large_count, 1)


def exact_fixed_point(words, unit_exponent):
    """The value of a record film's 128-bit sum (four uint32 words, least significant first, two's
    complement, units of 2^-FILM_FRACTION_BITS of 2^unit_exponent) as a float64."""
    n = sum(int(w) << (32 * k) for k, w in enumerate(words))
    if n >= 1 << 127:
        n -= 1 << 128
    return float(n) * 2.0 ** (int(unit_exponent) - FILM_FRACTION_BITS)


def systematic_picks(f, count, rng):
    """`count` indices into f drawn in proportion to f by systematic resampling: one uniform
    offset, `count` evenly spaced points on the cumulative f."""
    cdf = np.cumsum(f)
    pick = np.searchsorted(cdf, (rng.random() + np.arange(count)) / count * cdf[-1], side="right")
    return np.minimum(pick, len(f) - 1)
