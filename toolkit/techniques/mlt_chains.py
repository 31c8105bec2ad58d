"""The host's side of mlt's chains (toolkit/techniques/mlt.py): their device memory and current
states, the records that belong to chains, one iteration's evaluated proposals, and the sink
that keeps BDPT's connection records with their chains."""
from dataclasses import dataclass, field

import numpy as np
import pyopencl as cl

from toolkit.core.layout import LUMINANCE_WEIGHTS
from toolkit.core.sample_dims import BDPT_FIRST_SCATTER_DIM, used_dims   # the dimension table the kernels read


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
    f: np.ndarray          # (active,) float64 scalar contribution of each proposal: luminance of its records, >= 0
    dims: np.ndarray       # (active,) primary-sample dimensions each proposal used, at most max_dims


class ProposalSink:
    """Where BDPT's connect phases put the proposals' records: with their chains (sample id =
    chain), not in an image; and each connected sample's used dimensions."""

    def __init__(self, active):
        self.parts = []                                    # ChainRecords of each connect phase
        self.dims = np.full(active, BDPT_FIRST_SCATTER_DIM, np.int64)  # a proposal that never connects used the start's

    def add(self, connections):
        """Connections with their slots (ParallelConnect(read_slots=True)); none: nothing connected."""
        if connections.slots is None:
            return
        counts, slots = connections.slot_records, connections.slots
        done = counts > 0
        ids = slots["sample_id"][done]
        self.dims[ids] = used_dims(slots["eye_vertices"][done], slots["light_vertices"][done])
        chain = np.repeat(ids, counts[done])
        ok = connections.pixels >= 0
        self.parts.append(ChainRecords(connections.values[ok, :3].astype(np.float64), connections.pixels[ok],
                                       chain[ok]))

    def proposals(self, max_dims):
        """(Proposals, records dropped for a non-finite value, proposals that read more than max_dims)."""
        if self.parts:
            records = ChainRecords(*(np.concatenate(x) for x in
                                     zip(*((r.values, r.pixels, r.chain) for r in self.parts))))
        else:
            records = ChainRecords.empty()
        finite = np.isfinite(records.values).all(1)
        nonfinite = int((~finite).sum())
        if nonfinite:     # a bug to report (DroppedSamplesWarning), never a NaN in the chain
            records = records.where(finite)
        f = np.bincount(records.chain, records.values @ np.asarray(LUMINANCE_WEIGHTS), minlength=len(self.dims))
        overflow = int((self.dims > max_dims).sum())
        return Proposals(records, np.maximum(f, 0.0), np.minimum(self.dims, max_dims)), nonfinite, overflow


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
    f_proposal: cl.Buffer    # float[count], written by the host
    dims_proposal: cl.Buffer  # int[count], written by the host
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
    overflow: int = 0                   # proposals that read more than max_dims dimensions
    nonfinite: int = 0

    def __post_init__(self):
        self.f_current = np.zeros(self.count)
        self.current_records = ChainRecords.empty()
        self.splats, self.large_splats = np.zeros((self.pixels, 3)), np.zeros((self.pixels, 3))
        self.candidate_sum, self.weight = np.zeros(self.count), np.ones(self.count)

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
