"""Checks of the BSDFs in cl/materials.h from the host: sampling against the BSDF's own pdf.

`BsdfChecker` builds cl/bsdf_test.cl with every material compiled in and runs its two kernels:
`sample()` draws directions with `bsdf_sample`, `evaluate()` calls `bsdf_eval` at given
directions. `chi2_test()` is a Pearson chi-square goodness-of-fit test of the sampled
directions against the pdf that `bsdf_eval` reports, after Mitsuba's `chi2.py` (Jakob et al.):

- the sphere of directions is cut into bins that are equal-area: uniform in (z = cos theta,
  phi), since d(omega) = dz dphi (Archimedes' hat-box theorem). A band z in [z_lo, z_hi] can
  be chosen to resolve a narrow lobe; all directions outside the band, together with the
  failed samples, form one more cell whose expected count is N (1 - integral over the band);
- the expected count of each bin is N times the integral of the pdf over the bin, computed
  with tensor-product Gauss-Legendre rules (eval kernel), refined adaptively inside each
  bin until two levels agree (`bin_integrals`: a glossy lobe can be far narrower than a bin);
- cells with expected count below 5 are pooled (Mitsuba's rule: sorted by expected count,
  the smallest are merged until the pooled cell reaches 5);
- the statistic sum (O - E)^2 / E has (cells - 1) degrees of freedom; its p-value is the
  chi-square distribution's tail, the regularized upper incomplete gamma function
  Q(dof / 2, chi2 / 2) (from scipy). The statistic with its pooling, the tail and the Sidak
  correction are in `toolkit/core/stats.py`, shared with the render z-test.
"""
import math
from dataclasses import dataclass, field

import numpy as np
import pyopencl as cl
import pyopencl.cltypes as cltypes

from toolkit.opencl import program
from toolkit.opencl.device import get_queue
from toolkit.core.layout import MATERIAL, MATERIAL_TYPES
from toolkit.core.stats import chi2_sf, pearson

SOURCE = "bsdf_test.cl"


def defines():
    """Every material compiled in (the MAT_* type codes come with layout.h)."""
    return {f"HAS_{name.upper()}": 1 for name in MATERIAL_TYPES}


def material_record(material):
    """The `Material` record of a dict {"type", "reflectance" (3 numbers or one), "ior", "alpha"}."""
    rec = MATERIAL.zeros(1)[0]
    rec["type"] = MATERIAL_TYPES[material["type"]]
    rec["reflectance"][:3] = np.broadcast_to(np.asarray(material.get("reflectance", 0.0), np.float64), (3,))
    rec["ior"] = material.get("ior", 1.0)
    rec["alpha"] = material.get("alpha", 0.0)
    return rec


def direction(theta_deg, phi_deg=0.0):
    """The unit vector at polar angle theta from +z (theta > 90 deg: below the surface)."""
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])


def _float4(v):
    v = np.asarray(v, np.float64)
    return cltypes.make_float4(float(v[0]), float(v[1]), float(v[2]), 0.0)


@dataclass
class Samples:
    """What `bsdf_sample` returned for n draws (float32 arrays, as the device wrote them)."""
    wi: np.ndarray        # (n, 3); zero where the sample failed
    pdf: np.ndarray       # (n,); 0 for a specular choice, -1 where it failed
    weight: np.ndarray    # (n, 3)
    specular: np.ndarray  # (n,) bool
    ok: np.ndarray        # (n,) bool: the sample succeeded

    def __len__(self):
        return len(self.pdf)


class BsdfChecker:
    """cl/bsdf_test.cl built once for a queue (all materials); sample and evaluate on it."""

    def __init__(self, queue=None):
        self.queue = queue if queue is not None else get_queue()
        self.program = program.build(queue, SOURCE, defines())
        self._sample = program.kernel(self.program, "bsdf_test_sample")
        self._eval = program.kernel(self.program, "bsdf_test_eval")

    def sample(self, material, wo, n, seed=1):
        """n draws of `bsdf_sample(material, wo)`; draw i uses Philox (seed, i, 0, block 0)."""
        ctx, n = self.queue.context, int(n)
        size = 16 * program.padded(n)
        wi_pdf = cl.Buffer(ctx, cl.mem_flags.WRITE_ONLY, size)
        weight = cl.Buffer(ctx, cl.mem_flags.WRITE_ONLY, size)
        program.launch(self.queue, self._sample, n, material_record(material), _float4(wo),
                       np.uint32(seed), np.int32(n), wi_pdf, weight)
        a, b = np.empty((n, 4), np.float32), np.empty((n, 4), np.float32)
        cl.enqueue_copy(self.queue, a, wi_pdf)
        cl.enqueue_copy(self.queue, b, weight)
        ok = a[:, 3] >= 0.0
        return Samples(wi=a[:, :3], pdf=a[:, 3], weight=b[:, :3], specular=b[:, 3] > 0.5, ok=ok)

    def evaluate(self, material, wo, wi):
        """(f, pdf) of `bsdf_eval(material, wo, wi)` for directions wi of shape (n, 3)."""
        wi = np.asarray(wi)
        n = len(wi)
        host = np.zeros((program.padded(n), 4), np.float32)
        host[:n, :3] = wi
        ctx = self.queue.context
        wi_buf = cl.Buffer(ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=host)
        out = cl.Buffer(ctx, cl.mem_flags.WRITE_ONLY, host.nbytes)
        program.launch(self.queue, self._eval, n, material_record(material), _float4(wo),
                       np.int32(n), wi_buf, out)
        result = np.empty((n, 4), np.float32)
        cl.enqueue_copy(self.queue, result, out)
        return result[:, :3], result[:, 3]

    def pdf(self, material, wo, wi):
        return self.evaluate(material, wo, wi)[1]


# ---------------------------------------------------------------------------------------------
# Quadrature over (z, phi) rectangles, where d(omega) = dz dphi.
#
# A glossy lobe can be far narrower than a bin (alpha = 0.1 at grazing incidence: about 0.01
# rad in phi near the horizon), so each bin is integrated adaptively: a cell's k x k
# Gauss-Legendre estimate is compared with the sum over its four halves, and cells whose two
# estimates differ by more than rtol (relative) + atol (absolute) are split again.

def _gauss_legendre(k):
    x, w = np.polynomial.legendre.leggauss(k)
    return 0.5 * (x + 1.0), 0.5 * w   # on [0, 1]


def _cell_rule(z0, z1, p0, p1, k):
    """Directions (m, k*k, 3) and weights (m, k*k) of a k x k Gauss-Legendre rule on each cell
    [z0, z1] x [p0, p1]; the weights of a cell sum to its solid angle."""
    x, w = _gauss_legendre(k)
    dz, dp = (z1 - z0)[:, None], (p1 - p0)[:, None]
    z = z0[:, None] + dz * x[None, :]                       # (m, k)
    p = p0[:, None] + dp * x[None, :]
    zz = np.repeat(z, k, axis=1)                             # (m, k*k): z varies slowest
    pp = np.tile(p, (1, k))
    ww = (np.repeat(dz * w[None, :], k, axis=1) * np.tile(dp * w[None, :], (1, k)))
    s = np.sqrt(np.clip(1.0 - zz * zz, 0.0, None))
    return np.stack([s * np.cos(pp), s * np.sin(pp), zz], axis=-1), ww


def _cell_integrals(checker, material, wo, z0, z1, p0, p1, k):
    """(integral of the pdf, integral of f |cos theta_i|) over each cell, from bsdf_eval."""
    dirs, w = _cell_rule(z0, z1, p0, p1, k)
    f, pdf = checker.evaluate(material, wo, dirs.reshape(-1, 3))
    m = len(z0)
    pdf = pdf.astype(np.float64).reshape(m, -1)
    f_cos = f.astype(np.float64).reshape(m, -1, 3) * np.abs(dirs[..., 2:3])
    return (w * pdf).sum(1), (w[..., None] * f_cos).sum(1)


@dataclass
class BinIntegrals:
    pdf: np.ndarray        # (n_z, n_phi): integral of the pdf over each bin
    f_cos: np.ndarray      # (n_z, n_phi, 3): integral of f |cos theta_i| over each bin
    evaluations: int       # bsdf_eval calls spent
    unconverged: int       # cells still above the tolerance at max_depth (0 expected)


def bin_integrals(checker, material, wo, z_edges, phi_edges, k=4, rtol=1e-5, atol=1e-12,
                  max_depth=10):
    """Adaptive integrals of the pdf and of f |cos| over the bins z_edges x phi_edges.

    Keep z = 0 a bin edge: the reflection-only BSDFs jump to zero there."""
    z_edges, phi_edges = np.asarray(z_edges, np.float64), np.asarray(phi_edges, np.float64)
    n_z, n_phi = len(z_edges) - 1, len(phi_edges) - 1
    iz, ip = np.meshgrid(np.arange(n_z), np.arange(n_phi), indexing="ij")
    iz, ip = iz.ravel(), ip.ravel()
    owner = iz * n_phi + ip
    z0, z1, p0, p1 = z_edges[iz], z_edges[iz + 1], phi_edges[ip], phi_edges[ip + 1]
    est_pdf, est_fc = _cell_integrals(checker, material, wo, z0, z1, p0, p1, k)
    evaluations = len(z0) * k * k
    out_pdf, out_fc = np.zeros(n_z * n_phi), np.zeros((n_z * n_phi, 3))
    unconverged = 0
    for depth in range(1, max_depth + 1):
        zm, pm = 0.5 * (z0 + z1), 0.5 * (p0 + p1)
        # children in the order (lower z, lower phi), (lower, upper), (upper, lower), (upper, upper)
        cz0 = np.stack([z0, z0, zm, zm], 1).ravel()
        cz1 = np.stack([zm, zm, z1, z1], 1).ravel()
        cp0 = np.stack([p0, pm, p0, pm], 1).ravel()
        cp1 = np.stack([pm, p1, pm, p1], 1).ravel()
        c_pdf, c_fc = _cell_integrals(checker, material, wo, cz0, cz1, cp0, cp1, k)
        evaluations += len(cz0) * k * k
        sum_pdf, sum_fc = c_pdf.reshape(-1, 4).sum(1), c_fc.reshape(-1, 4, 3).sum(1)
        err = np.maximum(np.abs(sum_pdf - est_pdf), np.abs(sum_fc - est_fc).max(1))
        scale = np.maximum(np.abs(sum_pdf), np.abs(sum_fc).max(1))
        done = err <= rtol * scale + atol
        if depth == max_depth:
            unconverged = int((~done).sum())
            done[:] = True
        np.add.at(out_pdf, owner[done], sum_pdf[done])
        np.add.at(out_fc, owner[done], sum_fc[done])
        keep = np.repeat(~done, 4)
        if not keep.any():
            break
        owner = np.repeat(owner, 4)[keep]
        z0, z1, p0, p1 = cz0[keep], cz1[keep], cp0[keep], cp1[keep]
        est_pdf, est_fc = c_pdf[keep], c_fc[keep]
    return BinIntegrals(out_pdf.reshape(n_z, n_phi), out_fc.reshape(n_z, n_phi, 3),
                        evaluations, unconverged)


def sphere_edges(n_z=32, n_phi=64, z_range=(-1.0, 1.0)):
    """Equal-area bin edges: uniform in z = cos theta over z_range and in phi over [-pi, pi]."""
    return np.linspace(z_range[0], z_range[1], n_z + 1), np.linspace(-math.pi, math.pi, n_phi + 1)


def integrate(checker, material, wo, res=(32, 64), z_range=(-1.0, 1.0), **options):
    """(integral of the pdf, integral of f |cos theta_i| (3 channels)) over the directions with
    z in z_range (default: the whole sphere), adaptively (see `bin_integrals`)."""
    result = bin_integrals(checker, material, wo, *sphere_edges(*res, z_range=z_range), **options)
    return float(result.pdf.sum()), result.f_cos.sum(axis=(0, 1))


@dataclass
class Chi2Result:
    statistic: float
    dof: int
    p_value: float
    samples: int
    cells: int              # cells in the statistic after pooling
    pooled: int             # bins merged into the pooled cell
    integral: float         # integral of the pdf over the band (the expected fraction in the bins)
    failed: int             # samples that failed
    message: str = ""
    observed: np.ndarray = field(default=None, repr=False)   # (n_z, n_phi) counts
    expected: np.ndarray = field(default=None, repr=False)   # (n_z, n_phi) expected counts

    def passed(self, significance):
        return not self.message and self.p_value >= significance


def chi2_test(checker, material, wo, n_samples=1_000_000, seed=1, res=(48, 96),
              z_range=(-1.0, 1.0), pool_threshold=5.0, eval_material=None, **options):
    """Pearson chi-square test of `bsdf_sample` against the pdf of `bsdf_eval`.

    Bins: res = (n_z, n_phi) cells uniform in z = cos theta over z_range and phi over
    [-pi, pi) (equal solid angle), plus one cell for everything else (directions outside
    the band and failed samples). Expected counts: n_samples x (adaptive Gauss-Legendre
    integral of the pdf over the bin, `bin_integrals` with **options); the extra cell gets
    n_samples (1 - integral over the band). `eval_material` (default: `material`) is the
    material whose pdf the samples are compared with: a different one shows the test's power.
    """
    n_z, n_phi = res
    z_edges, phi_edges = sphere_edges(n_z, n_phi, z_range)
    integrals = bin_integrals(checker, eval_material or material, wo, z_edges, phi_edges, **options)
    integral = float(integrals.pdf.sum())
    expected = n_samples * integrals.pdf

    s = checker.sample(material, wo, n_samples, seed)
    wi = s.wi[s.ok].astype(np.float64)
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    z, phi = wi[:, 2], np.arctan2(wi[:, 1], wi[:, 0])
    iz = np.floor((z - z_range[0]) / (z_range[1] - z_range[0]) * n_z).astype(np.int64)
    iz = np.where(z == z_range[1], n_z - 1, iz)      # the top edge belongs to the last bin
    ip = np.clip(np.floor((phi + math.pi) / (2.0 * math.pi) * n_phi).astype(np.int64), 0, n_phi - 1)
    inside = (iz >= 0) & (iz < n_z)
    observed = np.bincount(iz[inside] * n_phi + ip[inside], minlength=n_z * n_phi)
    observed = observed.reshape(n_z, n_phi).astype(np.float64)
    rest_observed = n_samples - observed.sum()
    rest_expected = max(0.0, n_samples * (1.0 - integral))

    statistic, dof, cells, pooled, message = pearson(
        np.append(observed.ravel(), rest_observed), np.append(expected.ravel(), rest_expected),
        pool_threshold)
    if integrals.unconverged and not message:
        message = f"{integrals.unconverged} integration cells did not converge"
    if dof < 1 and not message:
        message = "fewer than two cells after pooling: the binning cannot resolve the lobe"
    p_value = 0.0 if message else chi2_sf(statistic, dof)
    return Chi2Result(statistic=statistic, dof=dof, p_value=p_value, samples=n_samples,
                      cells=cells, pooled=pooled, integral=integral,
                      failed=int((~s.ok).sum()), message=message,
                      observed=observed, expected=expected)
