"""Every layout and constant that host and device share, described once.

Each `Record` (toolkit/core/record.py) gives the numpy dtype (with C's offsets: a float4 is
16-byte aligned) and the C struct; each group of named values (an IntEnum) gives the Python
constants and C `#define`s. All of it is generated into `layout.h` (see `c_header()`), which
every program includes through cl/common.h, so host and device can never disagree.
`LAYOUT_CHECKS` lets a test kernel (cl/layout_check.cl) compare sizeof/offsetof of every struct
with numpy (tests/test_layout.py). The index formulas both sides compute
(toolkit/core/bdpt_indices.py, sample_dims.py) and the names of quantities packed into a float4's
.w component (packed_w.py) are emitted into layout.h here too.
"""
from enum import IntEnum, IntFlag

from toolkit.core import bdpt_indices, sample_dims
from toolkit.core.record import Record
from toolkit.core.packed_w import PackedW

# float4-first layouts keep every record 16-byte aligned on host and device alike.
BVH_NODE = Record("BvhNode", [
    ("lo", "float4"),   # box minimum; .w unused
    ("hi", "float4"),   # box maximum; .w unused
    ("first", "int"),   # leaf: first triangle; inner: index of the right child (left = this + 1)
    ("count", "int"),   # leaf: number of triangles (> 0); inner: 0
    ("axis", "int"),    # inner: split axis, to visit the nearer child first
    ("pad", "int"),
], "A flattened BVH node (depth-first order), 48 bytes.")

# The wide BVH (toolkit/core/bvh.py collapses the binary one): one work-item tests the child boxes
# of a node at once with vector operations, so each box coordinate is a vector holding it for all
# children (structure of arrays inside the node). Two widths (cl/bvh.h, NODE_WIDTH; which one a
# device gets: toolkit/opencl/device_scene.py node_width): 8 children in float8s (one AVX register)
# where work-items are threads, 4 in float4s where they are SIMD lanes.
def _wide_node(width):
    return Record(f"WideNode{width}", [
        ("lo_x", f"float{width}"), ("hi_x", f"float{width}"),   # child boxes, one lane per child
        ("lo_y", f"float{width}"), ("hi_y", f"float{width}"),
        ("lo_z", f"float{width}"), ("hi_z", f"float{width}"),
        # a child's reference (WideChild below): >= 0 an inner node, < 0 a leaf, or WIDE_EMPTY
        ("child", f"int{width}"),
    ], f"A node of the {width}-wide BVH, {28 * width} bytes. Records live in one buffer; a reference is the "
       "record's position in 16-byte words.")


WIDE_NODES = {4: _wide_node(4), 8: _wide_node(8)}   # by NODE_WIDTH

TRI_GROUP = Record("TriGroup", [
    # The vertices of four triangles, one lane per triangle: v0 x, y, z, then v1, then v2. The
    # three coordinates of a vertex follow each other, so the watertight test picks an axis
    # with an index (tri_group_coord in cl/bvh.h).
    ("v0x", "float4"), ("v0y", "float4"), ("v0z", "float4"),
    ("v1x", "float4"), ("v1y", "float4"), ("v1z", "float4"),
    ("v2x", "float4"), ("v2y", "float4"), ("v2z", "float4"),
    ("tri", "int4"),    # each lane's triangle (index into the leaf-order triangles), -1: an empty lane
], "A wide-BVH leaf: up to four triangles tested at once, 160 bytes.")

TRIANGLE = Record("Triangle", [
    ("v0", "float4"),   # .w unused
    ("v1", "float4"),   # the vertices themselves, not edges: a shared vertex is bit-identical
    ("v2", "float4"),   #   in every triangle, which the watertight ray test needs
    ("material", "int"),
    ("prim", "int"),    # index of the triangle in the scene (BVH order differs)
    ("light_pdf", "float"),  # density per unit area with which light sampling picks a point here
    ("light", "int"),        # index into the light array, -1: not a light
], "A triangle in BVH leaf order, 64 bytes.")

MATERIAL = Record("Material", [
    ("reflectance", "float4"),
    ("type", "int"),
    ("ior", "float"),
    ("alpha", "float"),
    ("pad", "int"),
], "A material of scenes/FORMAT.md; `type` is one of the MAT_* defines.")

LIGHT = Record("LightTri", [
    ("emission", "float4"),
    ("cdf", "float"),        # inclusive cumulative selection probability
    ("triangle", "int"),     # index into the triangle array (BVH order)
    ("pad0", "int"),
    ("pad1", "int"),
], "An emitting triangle, chosen for next-event estimation in proportion to its power.")

CAMERA = Record("Camera", [
    ("origin", "float4"),
    ("forward", "float4"),   # unit viewing direction f
    ("right", "float4"),     # r * tx (FORMAT.md)
    ("up", "float4"),        # u * ty
    ("width", "int"),
    ("height", "int"),
    ("pad0", "int"),
    ("pad1", "int"),
], "The pinhole camera of scenes/FORMAT.md, for the rendered resolution.")

PATH_STATE = Record("PathState", [
    ("origin", "float4"),      # next ray origin (already offset off the surface)
    ("dir", "float4"),         # next ray direction (unit)
    ("throughput", "float4"),  # product of BSDF weights so far
    ("radiance", "float4"),    # radiance gathered so far
    ("prev_pdf", "float"),     # solid-angle pdf of the BSDF sample that chose dir (for MIS)
    ("prev_specular", "int"),  # 1: dir came from the camera or a delta lobe
    ("bounce", "int"),         # surface vertices so far
    ("pixel", "int"),
    ("sample", "int"),         # sample index within the pixel: keys the random numbers
    ("slot", "int"),           # where the finished sample's radiance goes in this pass's output
    ("pad1", "int"),
    ("pad2", "int"),
], "The state of one camera path between two extension steps, 96 bytes.")

SHADOW_RAY = Record("ShadowRay", [
    ("origin", "float3"),        # where the segment to test starts (already offset off the surface)
    ("length", "float"),         # its length (in its stream it shares origin's 16 bytes: soa_arrays)
    ("dir", "float4"),           # its unit direction; .w unused
    ("contribution", "float4"),  # radiance added to the sample if the segment is unoccluded; .w unused
    ("slot", "int"),             # the sample's slot in the pass's output
], "A next-event-estimation shadow ray waiting to be traced, 52 bytes in its stream.")

HIT_RECORD = Record("HitRecord", [
    ("t", "float"),              # distance along the ray's unit direction
    ("tri", "int"),              # the triangle hit (index into tris), -1: the ray left the scene
], "The closest hit of a stream entry's ray, from the trace kernel to the shade kernel, 8 bytes in its stream.")

# The scalar arguments of the path tracers' kernels (cl/pt_*.cl), grouped as BDPT's are.
PT_PASS = Record("PtPass", [
    ("seed", "uint"),           # keys every random number, with the sample's pixel and number
    ("sample_base", "int"),     # samples per pixel of the passes before this one
    ("budget", "int"),          # samples in this pass: ids 0 .. budget - 1 (cl/camera.h's sample_pixel)
    ("capacity", "int"),        # records each path stream holds (a multiple of 4); pt_naive has no stream: 0
], "What every path-tracing kernel of one pass shares.")

PT_STEP = Record("PtStep", [
    ("length", "int"),          # paths this step extends: the last step's survivors, then the regenerated
    ("started", "int"),         # samples this step's regeneration started (at the end of the stream)
    ("survivors", "int"),       # paths that continue, packed into the next stream (compaction's counter)
    ("shadow_rays", "int"),     # shadow rays the step queued (immediate compaction's second counter)
    ("next_sample", "int"),     # id of the next sample of the budget to start, after this step's regeneration
], "One step of pt_compact_regen's stream, counted on the device: regeneration writes it from the last "
   "step's, the step's kernels read its length, compaction counts into it; the host reads it only now and then.")

BDPT_VERTEX = Record("BdptVertex", [
    ("pos", "float4"),       # position; .w unused
    ("normal", "float4"),    # geometric normal; .w unused
    ("wo", "float4"),        # unit direction to the previous vertex of the subpath
    ("beta", "float4"),      # subpath throughput up to this vertex (light paths: includes Le / pdf)
    ("material", "int"),
    ("flags", "int"),        # VERTEX_DELTA | VERTEX_CAMERA | VERTEX_LIGHT (VertexFlag below)
    ("light", "int"),        # index into the light array if the vertex lies on a light, else -1
    ("pdf_fwd", "float"),    # area density with which its own subpath generated this vertex
    ("pdf_rev", "float"),    # area density of generating the *previous* vertex of the subpath
                             #   from this one, in the reverse direction (0: not known yet)
    ("pad0", "int"),
    ("pad1", "int"),
    ("pad2", "int"),
], "A stored BDPT path vertex, 96 bytes (the talk's vertex is 128).")

SUBPATH = Record("Subpath", [
    ("origin", "float4"),     # next ray origin; .w: pdf_dir (SUBPATH_PACKED_W below)
    ("dir", "float4"),        # next ray direction
    ("beta", "float4"),       # throughput; .w: rr_normaliser (SUBPATH_PACKED_W below)
    ("prev_pos", "float4"),   # the last stored vertex (exact, not offset)
    ("prev_normal", "float4"),
    ("slot", "int"),          # the sample's slot in the sample pool
    ("vertices", "int"),      # vertices stored so far
    ("prev_flags", "int"),    # flags of the last stored vertex
    ("pad", "int"),
], "One eye or light subpath in a random-walk stream, 96 bytes.")

LANE_COUNTS = Record("LaneCounts", [
    ("work", "int"),           # the lane's work in this launch: 1 / 0 (active or not), or the
                               #   iterations of its loop (pt_naive) or its connections (bdpt_naive_connect)
    ("closest_steps", "int"),  # BVH nodes visited by closest-hit rays
    ("shadow_rays", "int"),    # shadow rays traced (or queued)
    ("shadow_steps", "int"),   # BVH nodes visited by shadow rays
], "What one lane (work-item) did in one launch, for the SIMD-efficiency model (COUNT_SIMD).")

SIMD_STEP = Record("SimdStep", [
    ("stride", "int"),          # ints per lane: 4 (LaneCounts) or 1 (an int per lane: its work)
    ("bound", "int"),           # lanes the host knows the step may have
    ("length_index", "int"),    # >= 0: the step's length is length_at[length_index] on the device (at most bound)
    ("warp_width", "int"),      # W of the counters
    ("watch_count", "int"),     # ints of `watch` the row keeps (at most SIMD_WATCH_INTS)
    ("bins", "int"),            # the per-iteration histogram's bins (its last holds any larger work)
    ("histogram_row", "int"),   # >= 0: the histogram column of this step
    ("histogram_rows", "int"),  # columns of the histogram
    ("slot_offset", "int"),     # where lane 0's slot is in slot_of (ints)
    ("aux_bound", "int"),       # ints of `aux` (one per lane) summed into the AUX_ fields; 0: none
], "One counting step for cl/simd_counters.cl simd_count_lanes (toolkit/opencl/simd_counters.py); its row of the "
   "step log and its stamp are arguments of their own, so that the steps of a loop share one record.")

BDPT_SLOT = Record("BdptSlot", [
    ("live", "int"),            # SLOT_IDLE, or how many of its subpaths still walk (SlotState below)
    ("sample_id", "int"),       # the sample in this slot: its id in the pass
    ("eye_vertices", "int"),    # vertices stored for its eye subpath
    ("light_vertices", "int"),  # vertices stored for its light subpath
    ("pixel", "int"),           # the sample's own pixel, where its eye strategies (t >= 2) land
], "One slot of the BDPT sample pool (one per sample in flight).")

BDPT_PASS = Record("BdptPass", [
    ("seed", "uint"),
    ("sample_base", "int"),     # samples per pixel of the passes before this one
    ("pool", "int"),            # samples in flight: slots of the pool
    ("capacity", "int"),        # records each subpath stream holds (pool rounded up, a multiple of 4)
    ("chains", "int"),          # mlt only: the stride of the stored primary-sample vectors (cl/mlt.h); else 0
    ("pixels", "int"),          # the camera's pixels (width x height): sample id -> pixel and number (bdpt_sampler)
], "What every BDPT kernel of one pass shares.")

BDPT_STEP = Record("BdptStep", [
    ("ring", "int"),            # the step's place in the counters' ring of lengths (WalkCounter.LENGTH_RING): step k % 3
    ("appended", "int"),        # subpaths regenerated onto each stream since the lengths in the ring were counted
    ("light", "int"),           # the stream this launch extends: 0 the eye stream, 1 the light stream
    # SIMD counters (COUNT_SIMD) the launch adds to the step log itself (cl/simd_counters.h simd_count_group):
    ("simd_row", "int"),        # its row of the log (simd_log), or -1: not counted by this launch
    ("simd_stamp", "int"),      # its stamp of the pool's warps (SimdSum.SLOT_WARPS)
    ("simd_warp_width", "int"),   # W, which divides the work-group's size
    ("simd_stamps_at", "int"),  # where in simd_log (uints) the pool warps' stamps start
], "One random-walk step of one stream (bdpt_extend, launched once per stream).")

BDPT_REGENERATION = Record("BdptRegeneration", [
    ("count", "int"),           # terminated slots listed for regeneration
    ("fresh", "int"),           # the first `fresh` of them start new samples; the rest go idle
    ("first_id", "int"),        # id of the first new sample (the others follow, consecutive pixels)
    ("ring", "int"),            # where the streams' lengths are (the next walk step's place in the ring, WalkCounter)
    ("appended", "int"),        # subpaths already appended after those lengths (BdptStep.appended)
    ("light", "int"),           # the stream this launch starts subpaths in: 0 eye (and the slots), 1 light
], "One regeneration step of the BDPT pool (bdpt_regenerate, launched once per stream).")

MLT_CHAIN = Record("MltChain", [
    ("f_current", "float"),     # scalar contribution (luminance of all strategies) of the current state
    ("dims_current", "int"),    # primary-sample dimensions the current state used (a prefix: cl/mlt.h)
    ("large_step", "int"),      # 1: this iteration's proposal was a large step (every dimension fresh)
    ("accepted", "int"),        # 1: this iteration's proposal became the current state
    ("acceptance", "float"),    # a = min(1, f(proposal) / f(current)): the proposal's splat weight
    ("candidates", "float"),    # start = resample: sum of f over the candidates seen so far
    ("f_proposal", "float"),    # this iteration's proposal's f (cl/mlt_contribution.h), as mlt_accept saw it
    ("dims_proposal", "int"),   # the dimensions it used
], "One Metropolis chain (cl/mlt.h); its primary-sample vector is stored apart, dimension-major.")

MLT_ITERATION = Record("MltIteration", [
    ("seed", "uint"),
    ("iteration", "int"),       # keys the mutation's random numbers (start candidates count too)
    ("chains", "int"),          # chains in all: the stride of the primary-sample vectors
    ("active", "int"),          # chains that mutate in this iteration (the first `active`)
    ("large_step", "float"),    # probability of a large step
    ("mode", "int"),            # MltMode: what the accept kernel does with the proposal
    ("unit_exponent", "int"),   # the record films' and b's fixed point counts units of 2^unit_exponent
    ("store_capacity", "int"),  # the records the next current-state store holds (mlt_keep_records)
], "What the mutate and accept kernels of one Metropolis iteration share.")

# One pixel of a path-tracing pass, summed on the device (cl/film_reduce.cl): the host adds these
# up in float64 (toolkit/core/film.py), so it reads a pixel's sums instead of every sample.
FILM_PIXEL = Record("FilmPixel", [
    ("sum", "float4"),          # .xyz: the sum of the pixel's finite samples in this pass; .w unused
    ("sum_sq", "float4"),       # .xyz: the sum of their squares (the standard error); .w unused
    ("missing", "int"),         # samples never written (.w still -1): a sample-accounting bug
    ("dropped", "int"),         # samples flagged non-finite (.w = 1): left out, counted, reported
    ("pad0", "int"),
    ("pad1", "int"),
], "A pixel's sums over one pass of samples, 48 bytes.")

RECORDS = [BVH_NODE, *WIDE_NODES.values(), TRI_GROUP, TRIANGLE, MATERIAL, LIGHT, CAMERA, PATH_STATE, SHADOW_RAY,
           HIT_RECORD, BDPT_VERTEX, SUBPATH, LANE_COUNTS, SIMD_STEP, BDPT_SLOT, BDPT_PASS, BDPT_STEP, BDPT_REGENERATION,
           MLT_CHAIN, MLT_ITERATION]
RECORDS += [PT_PASS, PT_STEP]   # the path tracers' kernel arguments and stream counts

# One pixel of the film that sums connection records on the device (cl/record_film.cl: BDPT's
# records, the light tracer's t = 1 splats). Each colour channel is an exact integer sum in units
# of 2^-FILM_FRACTION_BITS, 128 bits in two's complement, as four 32-bit words (least significant
# first): integer additions give the same bits in any order, so no float atomics are needed.
FILM_ACCUMULATOR = Record("FilmAccumulator", [
    ("red", "uint4"),
    ("green", "uint4"),         # the channels follow each other: channel c's words at 4 * c
    ("blue", "uint4"),
    ("dropped", "uint"),        # records left out: not finite, or beyond FILM_RECORD_LIMIT
    ("pad0", "uint"),
    ("pad1", "uint"),
    ("pad2", "uint"),
], "A pixel's exact sums of one pass of connection records, 64 bytes.")
RECORDS += [FILM_PIXEL, FILM_ACCUMULATOR]

SOA_RECORDS = [PATH_STATE, SHADOW_RAY, HIT_RECORD, SUBPATH]


# ---- named values, each group emitted as PREFIX_NAME defines --------------------------------

class MaterialType(IntEnum):
    """Material.type (scenes/FORMAT.md): MAT_DIFFUSE, ..."""
    DIFFUSE = 0
    MIRROR = 1
    DIELECTRIC = 2
    GLOSSY = 3


MATERIAL_TYPES = {m.name.lower(): int(m) for m in MaterialType}   # the scene format's names


class VertexFlag(IntFlag):
    """BdptVertex.flags: VERTEX_DELTA, ..."""
    DELTA = 1     # a specular bounce: cannot be connected
    CAMERA = 2    # z_0, the pinhole
    LIGHT = 4     # y_0, the point sampled on a light


class SlotState(IntEnum):
    """BdptSlot.live: how many of the sample's subpaths still walk, or idle (cl/bdpt_walk.h)."""
    CONNECTING = -2     # listed for the connect phase queued next (bdpt_mark_terminated): no longer counted as terminated
    IDLE = -1           # no sample (the pass's budget is spent)
    TERMINATED = 0      # both subpaths ended: the sample waits for its connections
    ONE_WALKING = 1
    BOTH_WALKING = 2    # just regenerated


class WalkCounter(IntEnum):
    """Indices into the random walk's counter buffer: the streams' lengths stay on the device, and
    the host reads the buffer behind the walk (bdpt_evaluator.py), not before each step. The lengths
    are a ring of three (eye, light) pairs, so that no step needs the host to clear or copy a count:
    walk step k reads pair k % 3, counts its survivors into pair (k + 1) % 3 (the next step's) and
    clears pair (k + 2) % 3 (the one after)."""
    TERMINATED_SAMPLES = 0  # samples whose second subpath ended and that no listing has listed yet
    STEP_EYE_LENGTH = 1     # the eye subpaths the last walk step extended (for the SIMD counters)
    STEP_LIGHT_LENGTH = 2   # the same for the light stream
    WALK_STEPS = 3          # the pass's walk steps so far that found subpaths to extend (in either stream)
    LENGTH_RING = 4         # pair r of the ring: eye length at LENGTH_RING + 2r, light length after it
    COUNTER_INTS = 10       # the buffer's ints: the four above and the ring's six


class ListingInt(IntEnum):
    """What the host reads of a listing of the terminated samples (cl/bdpt_walk.h bdpt_list_offsets,
    bdpt_evaluator.py Listing): one small buffer, read behind the walk."""
    LISTED = 0              # slots listed for the connect phase (0: too few had terminated)
    RECORDS = 1             # their records
    EYE_LENGTH = 2          # the streams' lengths when listed: they bound the host's later launches
    LIGHT_LENGTH = 3
    WALK_STEPS = 4          # WalkCounter.WALK_STEPS when listed: how long the pass's walk has been
    INTS = 5                # the buffer's ints


class WideChild(IntEnum):
    """WideNode.child: a lane that holds no child (references are >= 0 for inner nodes, ~position
    for leaves; no BVH buffer reaches 2^30 words, 16 GiB)."""
    EMPTY = -(1 << 30)


class MltMode(IntEnum):
    """MltIteration.mode: how mlt_mutate proposes and mlt_accept decides (cl/mlt.h)."""
    MUTATE = 0          # the Metropolis step: large step with probability large_step, else a small step
    START = 1           # start = naive: one large step, always accepted
    CANDIDATE = 2       # start = resample: a large step, kept with probability f / (sum of f so far)


class MltTally(IntEnum):
    """The render's integer counts that mlt's kernels keep on the device (cl/mlt_contribution.h),
    read once at the end of the render: the index of each in the tallies buffer."""
    NONFINITE = 0       # records dropped for a non-finite value (DroppedSamplesWarning)
    OVERFLOW = 1        # proposals that read more than max_dims dimensions
    ACCEPTED = 2        # accepted mutations (MltMode.MUTATE): the acceptance rate
    LARGE_STEPS = 3     # large steps whose f is in b's sum (cl/mlt_splat.h): b = sum / LARGE_STEPS
    STORE_OVERFLOW = 4  # records a current store had no room for: the host's bound is wrong, a bug (raised)


class SimdSum(IntEnum):
    """One row of the SIMD counters' step log (cl/simd_counters.cl, toolkit/opencl/simd_counters.py):
    what a counting step's lanes add up to, each sum a 64-bit integer held as two 32-bit words (low,
    high) so that every device can add to it exactly with 32-bit atomics. Lanes are the first LANES
    of the launch, in warps of W consecutive lanes; `work` is LaneCounts.work (or the one int per lane
    of an int buffer), `shadow` LaneCounts.shadow_rays; a warp "has" work if any of its lanes has."""
    LANES = 0               # lanes counted (the step's length: the host's, or read on the device)
    WORK_LANES = 1          # lanes with work > 0
    WORK_WARPS = 2          # warps with a lane with work > 0
    WORK_SUM = 3            # sum of work (a loop's lane-iterations)
    WORK_WARP_MAX = 4       # sum over warps of the warp's largest work (a loop's iterations per warp)
    WORK_MAX = 5            # the largest work of any lane
    CLOSEST_SUM = 6         # sum of closest_steps (BVH traversal of closest-hit rays)
    CLOSEST_WARP_MAX = 7    # sum over warps of the largest closest_steps
    SHADOW_LANES = 8        # lanes with shadow_rays > 0
    SHADOW_WARPS = 9        # warps with such a lane
    SHADOW_SUM = 10         # sum of shadow_rays
    SHADOW_STEPS_SUM = 11   # sum of shadow_steps (BVH traversal of shadow rays)
    SHADOW_STEPS_WARP_MAX = 12   # sum over warps of the largest shadow_steps
    SLOT_WARPS = 13         # warps of the sample pool holding a lane's slot (BDPT's walk without compaction)
    PACKED_WARP_MAX = 14    # sum over warps of the largest work, the lanes with work packed side by side
    AUX_COUNT = 15          # lanes of the step's second int buffer (aux) counted, summed in the same launch:
    AUX_LANES = 16          #   those with a value > 0,
    AUX_WARPS = 17          #   the warps with such a lane,
    AUX_SUM = 18            #   the sum of the values,
    AUX_WARP_MAX = 19       #   and the sum over warps of the largest value
    WATCH = 20              # WATCH_INTS ints copied from the device as the step was counted (its counts)
    FIELDS = 25             # fields per row (WATCH .. WATCH + 4 included)


NAMED_VALUES = [(MaterialType, "MAT_"), (WideChild, "WIDE_"), (VertexFlag, "VERTEX_"), (SlotState, "SLOT_"),
                (WalkCounter, ""), (ListingInt, "LISTING_"), (MltMode, "MLT_"), (MltTally, "MLT_TALLY_"), (SimdSum, "SIMD_")]
SIMD_WATCH_INTS = int(SimdSum.FIELDS - SimdSum.WATCH)   # ints a step's row keeps of the device's counts

# ---- single constants --------------------------------------------------------------------

# The most vertices a BDPT subpath stores (MAX_VERTICES of a scene with unbounded depth): the
# scene's largest max_depth, the vertex memory's size and mlt's largest max_dims derive from it.
LONGEST_SUBPATH = 64
# Paths without a depth limit or roulette still stop after this many bounces (cl/path.h); a path this
# long carries no measurable energy in any scene whose albedo is below one. It also bounds a lane's
# loop in pt_naive, which the SIMD counters' histogram holds (techniques/pt_naive.py).
HARD_MAX_BOUNCES = 1024
LOCAL_SIZE = 64                             # work-items per work-group by default (opencl/program.py)
BVH_STACK_SIZE = 64                         # entries of a traversal stack (cl/bvh.h); deeper BVHs are refused
BVH_WIDTH = 4                               # triangles of a TriGroup (float4 lanes)
BVH_KINDS = ("binary", "wide")              # --bvh: the traversal compiled in (BVH_WIDE for "wide")
LUMINANCE_WEIGHTS = (0.2126, 0.7152, 0.0722)   # Rec. 709 luminance of linear RGB
# A ray leaving a surface starts the scene's epsilon plus this many float32 ulps of its largest
# coordinate off it (cl/scene.h: ray_offset); the host's surface rays (peers/embree.py) do the same.
RAY_OFFSET_ULPS = 64.0
# The record film's fixed point (cl/record_film.cl), in units of a power of two near the scene's
# brightest light: a record is rounded to a multiple of 2^-48 units, so one of 2^-25 units (3e-8)
# or more is kept exactly (1e-6 has its last bit at 2^-43). A channel's 128 bits hold sums below
# 2^79; a pass adds fewer than 2^31 records to a pixel, so a record up to 2^47 units (1.4e14)
# never overflows it. A larger one is dropped and counted, as a non-finite one is (a connection
# 1e14 times brighter than the brightest light is a bug: a pdf near zero).
FILM_FRACTION_BITS = 48
FILM_RECORDS_PER_ITEM = 8   # consecutive records one work-item adds (a run on one pixel: one atomic)
FILM_RECORD_LIMIT = 2.0 ** 47

# The scene as kernel arguments, in order: SCENE_PARAMS (kernel parameters), SCENE_INIT (the
# SceneView made of them) and DeviceScene.args() (the host's values) all come from this list.
# `nodes` is BvhNode records for the binary BVH, and for the wide one (BVH_WIDE) a buffer of
# WideNode and TriGroup records addressed in 16-byte words (BVH_WORD).
SCENE_ARGS = [("nodes", "__global const BVH_WORD*"), ("tris", "__global const Triangle*"),
              ("materials", "__global const Material*"), ("lights", "__global const LightTri*"),
              ("light_count", "const int"), ("epsilon", "const float")]
# Their names as kernel parameters, by which the host passes them (Kernels.scene_args).
SCENE_PARAM_NAMES = [f"scene_{name}" for name, _ in SCENE_ARGS]

# What both BDPT connect kernels (cl/bdpt_naive_connect.cl, cl/bdpt_parallel_connect.cl) read and
# write, in order, after their own scalars: CONNECT_PARAMS. The host passes them in this order
# (the connect phases in toolkit/techniques/bdpt_*_connect.py).
CONNECT_ARGS = [("firsts", "__global const int*"),            # a scan of per-slot record counts
                ("slots", "__global const BdptSlot*"),        # the sample pool
                ("eye_vertices", "__global const BdptVertex*"), ("light_vertices", "__global const BdptVertex*"),
                ("record_value", "__global float4*"),          # connection records: RGB (.w: STRATEGY_IMAGES' MIS weight)
                ("record_pixel", "__global int*"),             # and their target pixel (-1: none)
                ("lane_counts", "__global LaneCounts*")]       # the SIMD counters


def _c_literal(value):
    return f"{value!r}f" if isinstance(value, float) else (f"({value})" if value < 0 else str(value))


def c_constants():
    lines = []
    for group, prefix in NAMED_VALUES:
        lines.append(f"/* {group.__doc__} */")
        lines += [f"#define {prefix}{m.name} {_c_literal(int(m))}" for m in group]
    lines.append(f"#define BVH_STACK_SIZE {BVH_STACK_SIZE}")
    lines.append(f"#define LONGEST_SUBPATH {LONGEST_SUBPATH}")
    lines.append(f"#define HARD_MAX_BOUNCES {HARD_MAX_BOUNCES}")
    lines.append(f"#define BVH_WIDTH {BVH_WIDTH}")
    lines.append("#ifdef BVH_WIDE\n#define BVH_WORD float4\n#else\n#define BVH_WORD BvhNode\n#endif")
    lines += [f"#define LUMINANCE_{c} {_c_literal(w)}" for c, w in zip("RGB", LUMINANCE_WEIGHTS)]
    lines.append(f"#define RAY_OFFSET_ULPS {_c_literal(RAY_OFFSET_ULPS)}")
    lines.append(f"#define FILM_FRACTION_BITS {FILM_FRACTION_BITS}")
    lines.append(f"#define FILM_SCALE {_c_literal(2.0 ** FILM_FRACTION_BITS)}")
    lines.append(f"#define FILM_RECORD_LIMIT {_c_literal(FILM_RECORD_LIMIT)}")
    lines.append(f"#define FILM_RECORDS_PER_ITEM {FILM_RECORDS_PER_ITEM}")
    lines.append("/* The scene as kernel parameters, and the SceneView (cl/scene.h) made of them. */")
    scene = list(zip(SCENE_ARGS, SCENE_PARAM_NAMES))
    lines.append("#define SCENE_PARAMS " + ", ".join(f"{t} {param}" for (_, t), param in scene))
    lines.append("#define SCENE_INIT {" + ", ".join(f".{n} = {param}" for (n, _), param in scene) + "}")
    lines.append("/* The pool and the records of both BDPT connect kernels (CONNECT_ARGS). */")
    lines.append("#define CONNECT_PARAMS " + ", ".join(f"{t} {name}" for name, t in CONNECT_ARGS))
    return "\n".join(lines)


def layout_checks(records=RECORDS):
    """(what, C expression, value numpy expects) for every generated struct."""
    return [check for r in records for check in r.layout_checks()]


def c_layout_checks(records=RECORDS):
    checks = layout_checks(records)
    body = " ".join(f"(out)[{i}] = (int)({expr});" for i, (_, expr, _) in enumerate(checks))
    return (f"/* For cl/layout_check.cl: sizeof and offsetof of every struct above, in layout_checks() order. */\n"
            f"#define LAYOUT_CHECK_COUNT {len(checks)}\n#define LAYOUT_CHECKS(out) {{ {body} }}")


def c_header(records=RECORDS):
    return ("/* Generated from toolkit/core/layout.py: do not edit by hand. */\n"
            + c_constants() + "\n\n"
            + "\n\n".join(r.c_struct() for r in records) + "\n\n"
            + "\n\n".join(r.c_soa() for r in SOA_RECORDS) + "\n\n"
            + c_layout_checks(records) + "\n\n"
            + c_shared_indices() + "\n\n"
            + c_packed_w() + "\n")


# ---- index arithmetic and sample-dimension tables (their own modules, emitted here) ----------

def c_shared_indices():
    """The sample-dimension tables (toolkit/core/sample_dims.py) and BDPT's connect-phase index
    arithmetic (toolkit/core/bdpt_indices.py), each written once in Python, as C."""
    return ("/* Sample dimensions (toolkit/core/sample_dims.py). */\n" + sample_dims.c_definitions() + "\n\n"
            + "/* BDPT's connect-phase indices (toolkit/core/bdpt_indices.py). */\n" + bdpt_indices.c_definitions())


# ---- quantities packed into the .w component of a float4 field (toolkit/core/packed_w.py) ----

SUBPATH_PACKED_W = [
    PackedW(SUBPATH, "origin", "pdf_dir", "solid-angle density of dir (delta_pdf_dir after a specular bounce)"),
    PackedW(SUBPATH, "beta", "rr_normaliser", "what roulette compares the throughput with: 1 for eye paths, "
                                              "max(beta) at y_1 for light paths (cl/bdpt_walk.h)"),
]


def c_packed_w():
    return "\n".join(packed.c_macro() for packed in SUBPATH_PACKED_W)
