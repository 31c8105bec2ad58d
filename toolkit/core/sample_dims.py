"""Which random number each sampling decision reads: the sample-dimension tables.

Every random number is dimension `dim` of its sample (cl/philox.h: a pure function of seed, pixel,
sample and dim), so a fixed table of dimensions makes bounce k always read the same ones: the
images do not depend on scheduling, and a Metropolis chain (cl/mlt_proposals.h) can perturb the
numbers one decision at a time. Emitted into layout.h (c_definitions); the host reads the same
table (used_dims, for MLT).

Path tracing: 2 for the pixel position, then PATH_DIMS_PER_BOUNCE per bounce from dimension
PATH_FIRST_BOUNCE_DIM, at the offsets of PathBounceDim.
Bidirectional path tracing (the order of the emitted names):
    0, 1                pixel position (eye)
    2                   which light;  3, 4  point on it;  5, 6  emission direction
    8 + 8(k-1) + 0..3   eye vertex k >= 1 scatters:   BSDF u, v, lobe, roulette
    8 + 8(k-1) + 4..7   light vertex k >= 1 scatters: BSDF u, v, lobe, roulette
Connections consume no random numbers (s = 1 uses the light subpath's first vertex).
"""
from enum import IntEnum

from toolkit.core.c_formula import c_defines, c_helper, where


class PathDim(IntEnum):
    """A path-tracing sample's dimensions before its bounces: DIM_PIXEL (2: x, y)."""
    PIXEL = 0


class PathBounceDim(IntEnum):
    """Offsets within one bounce of a path-tracing sample (bounce_dim): DIM_LIGHT_PICK, ..."""
    LIGHT_PICK = 0      # next-event estimation: which light, and the point on it (u, v)
    LIGHT_U = 1
    LIGHT_V = 2
    BSDF_U = 3          # the BSDF sample: direction (u, v) and lobe
    BSDF_V = 4
    BSDF_LOBE = 5
    ROULETTE = 6


PATH_FIRST_BOUNCE_DIM = 4
PATH_DIMS_PER_BOUNCE = 8


def bounce_dim(bounce, offset):
    """Dimension `offset` (PathBounceDim) of bounce `bounce` of a path-tracing sample."""
    return PATH_FIRST_BOUNCE_DIM + bounce * PATH_DIMS_PER_BOUNCE + offset


class BdptDim(IntEnum):
    """A bidirectional sample's dimensions before its scattering vertices: BDPT_DIM_PIXEL, ..."""
    PIXEL = 0           # 2: the position on the image
    LIGHT_PICK = 2      # which light
    LIGHT_POINT = 3     # 2: the point on it
    EMIT_DIR = 5        # 2: the emission direction (dimension 7 is spare)


class BdptScatterDim(IntEnum):
    """Offsets of one scattering vertex's dimensions (bdpt_scatter_dim): BDPT_SCATTER_BSDF_U, ..."""
    BSDF_U = 0
    BSDF_V = 1
    BSDF_LOBE = 2
    ROULETTE = 3


BDPT_FIRST_SCATTER_DIM = 8     # dimensions of the sample's start (BdptDim, and one spare)
BDPT_DIMS_PER_VERTEX = 8       # an eye and a light vertex of the same index k
BDPT_LIGHT_SCATTER_OFFSET = 4  # the light vertex's half of them


def bdpt_scatter_dim(vertex, light_path, offset):
    """Dimension `offset` (BdptScatterDim) of the scattering at vertex k = `vertex` >= 1 of the eye or light subpath."""
    return (BDPT_FIRST_SCATTER_DIM + BDPT_DIMS_PER_VERTEX * (vertex - 1)
            + where(light_path, BDPT_LIGHT_SCATTER_OFFSET, 0) + offset)


def used_dims(eye_vertices, light_vertices):
    """Dimensions a BDPT sample used (a prefix of the table): vertex k >= 1 of either subpath
    scatters with dimensions 8 + 8 (k - 1) .. 8 + 8 k - 1, and the last stored vertex may have."""
    longer = where(eye_vertices >= light_vertices, eye_vertices, light_vertices)
    return BDPT_FIRST_SCATTER_DIM + BDPT_DIMS_PER_VERTEX * (longer - 1)


def c_definitions():
    """The tables as C: the names as #defines, the formulas as helpers (c_formula.c_helper)."""
    return "\n".join([
        c_defines(PathDim, "DIM_"), c_defines(PathBounceDim, "DIM_"),
        f"#define DIMS_PER_BOUNCE {PATH_DIMS_PER_BOUNCE}",
        c_helper(bounce_dim, [("bounce", "int"), ("offset", "uint")], "uint"),
        c_defines(BdptDim, "BDPT_DIM_"), c_defines(BdptScatterDim, "BDPT_SCATTER_"),
        c_helper(bdpt_scatter_dim, [("vertex", "int"), ("light_path", "bool"), ("offset", "uint")], "uint"),
        c_helper(used_dims, [("eye_vertices", "int"), ("light_vertices", "int")])])
