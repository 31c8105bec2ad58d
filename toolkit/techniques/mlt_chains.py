"""The host's side of mlt's chains (toolkit/techniques/mlt.py): their device memory and current
states, the records that belong to chains, one iteration's evaluated proposals, and the sink
that keeps BDPT's connection records with their chains."""
from dataclasses import dataclass, field

import numpy as np
import pyopencl as cl

from toolkit.core.layout import MltTally
from toolkit.core.sample_dims import BDPT_FIRST_SCATTER_DIM   # the dimension table the kernels read


@dataclass
class ChainRecords:
    """Connection records that belong to chains."""
    values: np.ndarray     # (n, 3) float64 RGB (MIS-weighted)
    pixels: np.ndarray     # (n,) the pixel each record lands on
    chain: np.ndarray      # (n,) the chain (the BDPT sample id) each record belongs to

    @classmethod
    def empty(cls):
        return cls(np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64))

    def where(self, keep):
        """The records where `keep` (a mask or indices) holds."""
        return ChainRecords(self.values[keep], self.pixels[keep], self.chain[keep])

    def then(self, more):
        """These records followed by `more`."""
        return ChainRecords(*(np.concatenate([a, b]) for a, b in
                              ((self.values, more.values), (self.pixels, more.pixels), (self.chain, more.chain))))


@dataclass
class Proposals:
    """One iteration's proposals, evaluated as a batch of BDPT samples (sample id = chain)."""
    records: ChainRecords  # every connection record of every proposal
    f: np.ndarray          # (active,) scalar contribution of each proposal: luminance of its records, >= 0 (float32)
    dims: np.ndarray       # (active,) primary-sample dimensions each proposal used, at most max_dims


class ProposalSink:
    """Where BDPT's connect phases put the proposals' records (sample id = chain). Each proposal's
    contribution f and used dimensions are summed on the device, in the chains' f_proposal and
    dims_proposal (cl/mlt_contribution.h, mlt_proposal_sums: no record is read for them); the
    records themselves go to the host, with their chains, for the splats."""

    def __init__(self, kernels, chains, active):
        self.kernels, self.chains, self.active = kernels, chains, active
        self.parts = []                                    # ChainRecords of each connect phase
        queue = kernels.queue
        # a proposal that never connects has f = 0 and used the start's dimensions
        cl.enqueue_fill_buffer(queue, chains.f_proposal, np.float32(0), 0, 4 * active)
        cl.enqueue_fill_buffer(queue, chains.dims_proposal, np.int32(BDPT_FIRST_SCATTER_DIM), 0, 4 * active)

    def add(self, connections):
        """Connections with their slots (ParallelConnect(read_slots=True)); none: nothing connected."""
        if connections.slots is None:
            return
        c, pool = self.chains, len(connections.slots)
        self.kernels.launch("mlt_proposal_sums", pool, pool=np.int32(pool), slots=connections.slot_buffer,
                            counts=connections.count_buffer, firsts=connections.first_buffer,
                            record_value=connections.value_buffer, record_pixel=connections.pixel_buffer,
                            f_proposal=c.f_proposal, dims_proposal=c.dims_proposal, tallies=c.tallies)
        counts, slots = connections.slot_records, connections.slots
        done = counts > 0
        chain = np.repeat(slots["sample_id"][done], counts[done])
        values = connections.values[:, :3]
        # as the device's sums: a record without a pixel, or non-finite (counted there), adds nothing
        ok = (connections.pixels >= 0) & np.isfinite(values).all(1)
        self.parts.append(ChainRecords(values[ok].astype(np.float64), connections.pixels[ok], chain[ok]))

    def records(self):
        """The proposals' records, with their chains (f and dims stay on the device: mlt_accept
        reads them there, and the host gets them with the chains' decisions, MltChain)."""
        if not self.parts:
            return ChainRecords.empty()
        return ChainRecords(*(np.concatenate(x) for x in zip(*((r.values, r.pixels, r.chain) for r in self.parts))))


@dataclass
class Chains:
    """The chains' device memory and the host's view of their current states: whole once made
    (the host's arrays for `count` chains and `pixels` pixels start empty), then changed only by
    the iterations."""
    count: int
    seed: np.uint32          # the render's seed
    camera: np.void          # Camera record
    current: cl.Buffer       # float[max_dims][count]: the current states' primary-sample vectors
    proposal: cl.Buffer      # float[max_dims][count]: this iteration's proposals
    records: cl.Buffer       # MltChain[count]
    f_proposal: cl.Buffer    # float[count]: each proposal's f, summed on the device (ProposalSink)
    dims_proposal: cl.Buffer  # int[count]: the dimensions each proposal used, likewise
    tallies: cl.Buffer       # int[len(MltTally)]: the render's counts kept on the device, read at its end
    pixels: int              # of the image the chains splat into
    iteration: int = 0
    f_current: np.ndarray = field(init=False)          # float64 f of each current state
    current_records: ChainRecords = field(init=False)  # the current states' connection records
    splats: np.ndarray = field(init=False)         # (pixels, 3) float64 sum of the Metropolis splats (times b at the end)
    large_splats: np.ndarray = field(init=False)   # (pixels, 3) float64 sum of the large steps' own splats (combine)
    candidate_sum: np.ndarray = field(init=False)  # start = resample: sum of f over each chain's candidates
    weight: np.ndarray = field(init=False)         # each chain's splat weight: 1, or w_c / mean(w) (resample)
    large_sum: float = 0.0              # sum of f over the large steps (for b)
    large_count: int = 0
    accepted: int = 0
    mutations: int = 0
    overflow: int = 0                   # proposals that read more than max_dims dimensions (read_tallies)
    nonfinite: int = 0                  # records dropped for a non-finite value (read_tallies)

    def __post_init__(self):
        self.f_current = np.zeros(self.count)
        self.current_records = ChainRecords.empty()
        self.splats, self.large_splats = np.zeros((self.pixels, 3)), np.zeros((self.pixels, 3))
        self.candidate_sum, self.weight = np.zeros(self.count), np.ones(self.count)

    def read_tallies(self, memory):
        """The counts the kernels kept (MltTally), read once: at the end of the render."""
        tallies = memory.read_ints(self.tallies, len(MltTally))
        self.nonfinite, self.overflow = int(tallies[MltTally.NONFINITE]), int(tallies[MltTally.OVERFLOW])

    @property
    def b(self):
        """The estimate of b: the mean f of the large steps so far."""
        return self.large_sum / max(self.large_count, 1)

    def replace_accepted(self, accepted, proposals):
        """The accepted proposals (mask over the first chains) become those chains' current states."""
        active = len(accepted)
        replaced = np.zeros(self.count, bool)
        replaced[:active] = accepted
        kept = self.current_records.where(~replaced[self.current_records.chain])
        self.current_records = kept.then(proposals.records.where(replaced[proposals.records.chain]))
        self.f_current[:active][accepted] = proposals.f[accepted]


def systematic_picks(f, count, rng):
    """`count` indices into f drawn in proportion to f by systematic resampling: one uniform
    offset, `count` evenly spaced points on the cumulative f."""
    cdf = np.cumsum(f)
    pick = np.searchsorted(cdf, (rng.random() + np.arange(count)) / count * cdf[-1], side="right")
    return np.minimum(pick, len(f) - 1)


def records_of_picks(candidates, pick, count):
    """The records of the picked candidates (entry k * count + chain of `candidates`, a list of
    Proposals), as the records of chains 0 .. count - 1 (a candidate picked by several chains is
    copied to each)."""
    key = np.concatenate([k * count + x.records.chain for k, x in enumerate(candidates)])
    order = np.argsort(key, kind="stable")
    lo, hi = np.searchsorted(key[order], pick, "left"), np.searchsorted(key[order], pick, "right")
    n = hi - lo
    rows = order[np.repeat(lo - np.cumsum(n) + n, n) + np.arange(n.sum())]
    return ChainRecords(np.concatenate([x.records.values for x in candidates])[rows],
                        np.concatenate([x.records.pixels for x in candidates])[rows], np.repeat(np.arange(count), n))
