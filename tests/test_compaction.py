"""Stream compaction (cl/compact.h, cl/compact.cl, toolkit/opencl/compaction.py) against numpy.

Multi-pass must give np.flatnonzero(mask) exactly (stable). Immediate gives the alive set in
unspecified work-group order: we check the set (sorted output == flatnonzero, which also
rules out duplicates), the count, and that each work-group's survivors form one contiguous,
ascending run. pyopencl's own scan/copy_if serve as a second reference (they need Mako).
"""
import numpy as np
import pyopencl as cl
import pyopencl.array as cl_array
import pytest

from toolkit.opencl import device

from toolkit.opencl import program
from toolkit.opencl.compaction import Compactor

L = program.LOCAL_SIZE
METHODS = ["immediate", "multipass"]
# The work-group sizes every compaction test runs at (the kernels' scans and local arrays are
# sized by the LOCAL_SIZE define; a GPU may prefer another size than the CPU's default).
LOCAL_SIZES = [32, 64, 256]


@pytest.fixture(scope="module")
def queue():
    return device.get_queue()


@pytest.fixture(scope="module", params=LOCAL_SIZES, ids=lambda size: f"L{size}")
def compactor(queue, request):
    c = Compactor(queue, local_size=request.param)
    assert c.local_size == request.param
    return c


def check(method, out, mask, local_size=L):
    """Assert that `out` is a correct compaction of `mask` for `method` (by work-groups of
    `local_size`)."""
    expected = np.flatnonzero(mask)
    assert out.dtype == np.int32
    if method == "multipass":
        np.testing.assert_array_equal(out, expected)
        return
    assert len(out) == len(expected)
    np.testing.assert_array_equal(np.sort(out), expected)  # same set, no duplicates
    groups = out // local_size
    same_group = np.diff(groups) == 0
    # Each work-group's survivors are one contiguous run (one atomic per group) ...
    runs = int(np.count_nonzero(~same_group)) + 1 if len(out) else 0
    assert runs == len(np.unique(groups))
    # ... in local-id order.
    assert np.all(np.diff(out)[same_group] > 0)


# -- sizes, densities, edge cases -----------------------------------------------------------

@pytest.mark.parametrize("n", [1, 64, 65, 4097])
def test_multipass_compaction_on_device_leaves_the_count_there(queue, compactor, n, monkeypatch):
    """compact_on_device (what pt_compact_regen's multi-pass compaction calls every step) reads
    nothing back: the survivors' count is in a device buffer for the kernels queued next."""
    mask = (np.random.default_rng(n).random(n) < 0.4).astype(np.int32)
    flags = cl_array.to_device(queue, mask)
    out = cl.Buffer(queue.context, cl.mem_flags.READ_WRITE, 4 * n)
    reads, real_copy = [], cl.enqueue_copy
    with monkeypatch.context() as patch:
        patch.setattr(cl, "enqueue_copy", lambda *args, **kwargs: reads.append(args) or real_copy(*args, **kwargs))
        buffer, count = compactor.compact_on_device(flags.data, n, out=out)
    assert reads == [] and buffer is out and compactor.last_stats["count"] is None
    survivors, indices = np.empty(1, np.int32), np.empty(n, np.int32)
    cl.enqueue_copy(queue, survivors, count)
    cl.enqueue_copy(queue, indices, out)
    assert survivors[0] == mask.sum()
    np.testing.assert_array_equal(indices[:survivors[0]], np.flatnonzero(mask))


@pytest.mark.parametrize("method", METHODS)
def test_empty_stream_compacts_to_nothing(compactor, method):
    out = compactor.compact_numpy(np.zeros(0, bool), method)
    assert out.shape == (0,) and out.dtype == np.int32
    buffer, count = compactor.compact_indices(np.zeros(0, np.int32), 0, method)
    assert count == 0 and buffer.size >= 4
    assert compactor.last_stats["n"] == 0 and compactor.last_stats["count"] == 0


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("n", [1, 63, 64, 65, 1000, 4097])
@pytest.mark.parametrize("density", [0.0, 0.1, 0.5, 0.9, 1.0])
def test_compaction_matches_numpy_at_every_size_and_density(compactor, method, n, density):
    rng = np.random.default_rng(1000 * n + int(100 * density))
    mask = rng.random(n) < density
    out = compactor.compact_numpy(mask, method)
    check(method, out, mask, compactor.local_size)
    assert compactor.last_stats["n"] == n
    assert compactor.last_stats["work_groups"] == -(-n // compactor.local_size)
    assert compactor.last_stats["count"] == int(mask.sum())
    assert compactor.last_stats["method"] == method


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("density", [0.001, 0.3, 0.999])
def test_medium_stream_compacts_like_numpy_at_any_density(compactor, method, density):
    rng = np.random.default_rng(7)
    mask = rng.random(100_003) < density
    check(method, compactor.compact_numpy(mask, method), mask, compactor.local_size)


@pytest.mark.parametrize("method", METHODS)
def test_structured_masks_compact_like_numpy(compactor, method):
    """Patterns random masks rarely make: alternating lanes, whole dead groups, one survivor."""
    L = compactor.local_size
    n = L * 37 + 5
    masks = [np.arange(n) % 2 == 0,
             (np.arange(n) // L) % 3 == 1,           # every third work-group fully alive
             np.arange(n) == n - 1,                   # only the last item, in the padded group
             np.arange(n) % L == L - 1]               # only the last lane of every group
    for mask in masks:
        check(method, compactor.compact_numpy(mask, method), mask, L)


@pytest.mark.parametrize("method", METHODS)
def test_large_stream_compacts_like_numpy(queue, compactor, method):
    n = 4_000_000  # levels of block sums for the multi-pass scan: at L = 64 three (62500, 977, 16)
    mask = np.random.default_rng(4).random(n) < 0.35
    flags = cl_array.to_device(queue, mask.astype(np.int32))
    buffer, count = compactor.compact_indices(flags.data, n, method)
    out = np.empty(count, np.int32)
    cl.enqueue_copy(queue, out, buffer)
    check(method, out, mask, compactor.local_size)
    if method == "multipass":
        levels, blocks = 1, -(-n // compactor.local_size)
        while blocks > 1:
            levels, blocks = levels + 1, -(-blocks // compactor.local_size)
        # at L = 64: 4 scan levels, 3 add-backs, the scatter
        assert compactor.last_stats["launches"] == levels + (levels - 1) + 1


# -- inputs ---------------------------------------------------------------------------------

@pytest.mark.parametrize("method", METHODS)
def test_flags_past_n_are_ignored(queue, compactor, method):
    """The padding work-items of the last group read nothing and count as dead, even when the
    buffer holds alive flags beyond n."""
    L = compactor.local_size
    flags = cl_array.to_device(queue, np.ones(3 * L, np.int32))
    buffer, count = compactor.compact_indices(flags.data, L + 1, method)
    out = np.empty(count, np.int32)
    cl.enqueue_copy(queue, out, buffer)
    check(method, out, np.ones(L + 1, bool), L)


@pytest.mark.parametrize("method", METHODS)
def test_any_nonzero_flag_of_any_input_kind_is_alive(queue, compactor, method):
    rng = np.random.default_rng(11)
    values = rng.integers(-3, 4, 5000).astype(np.int32)   # any nonzero int is alive
    mask = values != 0
    for flags in (values, mask, mask.astype(np.uint8),
                  cl_array.to_device(queue, values), cl_array.to_device(queue, mask.astype(np.uint8))):
        buffer, count = compactor.compact_indices(flags, len(values), method)
        out = np.empty(count, np.int32)
        cl.enqueue_copy(queue, out, buffer)
        check(method, out, mask, compactor.local_size)


def test_reused_output_buffer_restarts_its_counter(queue, compactor):
    """Repeated calls into one output buffer: the atomic counter starts at zero every time."""
    n = 3000
    out = cl.Buffer(queue.context, cl.mem_flags.READ_WRITE, 4 * n)
    for seed in range(3):
        mask = np.random.default_rng(seed).random(n) < 0.5
        for method in METHODS:
            buffer, count = compactor.compact_indices(mask, n, method, out=out)
            assert buffer is out and count == int(mask.sum())
            result = np.empty(count, np.int32)
            cl.enqueue_copy(queue, result, out)
            check(method, result, mask, compactor.local_size)


def test_unknown_method_is_refused(compactor):
    with pytest.raises(ValueError):
        compactor.compact_numpy(np.ones(4, bool), "bogus")


# -- pyopencl as a second reference -----------------------------------------------------------

def test_multipass_matches_pyopencl_copy_if(queue, compactor):
    pytest.importorskip("mako", reason="pyopencl.algorithm needs Mako")
    from pyopencl.algorithm import copy_if
    n = 50_000
    mask = np.random.default_rng(5).random(n) < 0.3
    flags = cl_array.to_device(queue, mask.astype(np.int32))
    indices = cl_array.arange(queue, n, dtype=np.int32)
    reference, ref_count, _ = copy_if(indices, "flags[i] != 0", extra_args=[("flags", flags)], queue=queue)
    ref_count = int(ref_count.get())
    buffer, count = compactor.compact_indices(flags.data, n, "multipass")
    out = np.empty(count, np.int32)
    cl.enqueue_copy(queue, out, buffer)
    assert count == ref_count
    np.testing.assert_array_equal(out, reference[:ref_count].get())


def test_exclusive_scan_matches_generic_scan_kernel(queue, compactor):
    pytest.importorskip("mako", reason="pyopencl.scan needs Mako")
    from pyopencl.scan import GenericScanKernel
    n = 300_001
    values = np.random.default_rng(6).integers(0, 5, n).astype(np.int32)
    src = cl_array.to_device(queue, values)
    reference = cl_array.empty_like(src)
    scan = GenericScanKernel(queue.context, np.int32, arguments="__global const int *ary, __global int *out",
                             input_expr="ary[i]", scan_expr="a+b", neutral="0",
                             output_statement="out[i] = prev_item;")
    scan(src, reference, queue=queue)
    buffer, total = compactor.exclusive_scan(src.data, n)
    out = np.empty(n, np.int32)
    cl.enqueue_copy(queue, out, buffer)
    expected = reference.get()
    np.testing.assert_array_equal(expected[:3], np.cumsum(values)[:3] - values[:3])  # the reference is exclusive
    np.testing.assert_array_equal(out, expected)
    assert total == int(values.sum())
    # In place (dst = src) is allowed too.
    _, total_in_place = compactor.exclusive_scan(src.data, n, out=src.data)
    assert total_in_place == total
    np.testing.assert_array_equal(src.get(), expected)


# -- the device-side helper, as a path-tracing kernel would use it ------------------------------

RECORD_KERNELS = r"""
typedef struct { float4 payload; int source; int generation; int pad0; int pad1; } Record;

/* Partition a stream of records: survivors to `alive_out`, the rest to `dead_out`. The helper
 * is called twice with the same scratch (a kernel compacting in a loop does the same). */
__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))
void partition_records(__global const Record* in, __global const int* keep, const int n,
                       volatile __global int* counters, __global Record* alive_out,
                       __global Record* dead_out)
{
    __local int scratch[COMPACT_SCRATCH_INTS];
    int gid = get_global_id(0);
    bool valid = gid < n;  /* no early return: everyone must reach the helper's barriers */
    Record r;
    if (valid) r = in[gid];
    bool alive = valid && keep[gid] != 0;
    int slot = immediate_compact_slot(alive, scratch, &counters[0]);
    if (slot >= 0) {
        r.payload *= 2.0f;
        r.source = gid;
        r.generation += 1;
        alive_out[slot] = r;
    }
    int dead_slot = immediate_compact_slot(valid && !alive, scratch, &counters[1]);
    if (dead_slot >= 0) {
        r.source = gid;
        dead_out[dead_slot] = r;
    }
}
"""

RECORD = np.dtype([("payload", np.float32, 4), ("source", np.int32), ("generation", np.int32),
                   ("pad0", np.int32), ("pad1", np.int32)])


@pytest.fixture(scope="module", params=LOCAL_SIZES, ids=lambda size: f"L{size}")
def record_program(queue, request):
    """compact.h inlined the way program.build does it for a technique's kernel file, and the
    local size it is built for."""
    source = program.expand_includes("compact.h") + RECORD_KERNELS
    options = program.define_options({"LOCAL_SIZE": request.param})
    return cl.Program(queue.context, source).build(options=options), request.param


@pytest.mark.parametrize("n", [1, 65, 4097, 200_000])
def test_device_helper_compacts_struct_records(queue, record_program, n):
    record_program, L = record_program
    assert RECORD.itemsize == 32
    rng = np.random.default_rng(n)
    records = np.zeros(n, RECORD)
    records["payload"] = rng.random((n, 4), dtype=np.float32)
    records["generation"] = rng.integers(0, 10, n)
    records["source"] = -1
    keep = (rng.random(n) < 0.4).astype(np.int32)
    mf = cl.mem_flags
    ctx = queue.context
    in_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=records)
    keep_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=keep)
    counters = cl.Buffer(ctx, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=np.zeros(2, np.int32))
    alive_buf = cl.Buffer(ctx, mf.READ_WRITE, RECORD.itemsize * n)
    dead_buf = cl.Buffer(ctx, mf.READ_WRITE, RECORD.itemsize * n)
    kernel = cl.Kernel(record_program, "partition_records")
    program.launch(queue, kernel, n, in_buf, keep_buf, np.int32(n), counters, alive_buf, dead_buf, local_size=L)
    counts = np.empty(2, np.int32)
    cl.enqueue_copy(queue, counts, counters)
    alive_idx, dead_idx = np.flatnonzero(keep), np.flatnonzero(keep == 0)
    assert counts.tolist() == [len(alive_idx), len(dead_idx)]
    alive = np.empty(n, RECORD)
    dead = np.empty(n, RECORD)
    cl.enqueue_copy(queue, alive, alive_buf)
    cl.enqueue_copy(queue, dead, dead_buf)
    alive, dead = alive[:counts[0]], dead[:counts[1]]
    check("immediate", alive["source"], keep != 0, L)
    check("immediate", dead["source"], keep == 0, L)
    # Payloads travel with their records (exact: multiplying by 2 is exact in float).
    np.testing.assert_array_equal(alive["payload"], 2.0 * records["payload"][alive["source"]])
    np.testing.assert_array_equal(alive["generation"], records["generation"][alive["source"]] + 1)
    np.testing.assert_array_equal(dead["payload"], records["payload"][dead["source"]])
    np.testing.assert_array_equal(dead["generation"], records["generation"][dead["source"]])


def test_exclusive_scan_on_a_fresh_compactor(queue):
    """exclusive_scan works as the first call on a new Compactor (it once relied on state set
    by compact_indices)."""
    import pyopencl as cl
    from toolkit.opencl.compaction import Compactor
    counts = np.array([0, 3, 0, 2, 8, 0, 5, 7], np.int32)
    buf = cl.Buffer(queue.context, cl.mem_flags.READ_WRITE | cl.mem_flags.COPY_HOST_PTR, hostbuf=counts)
    out, total = Compactor(queue).exclusive_scan(buf, len(counts))
    firsts = np.empty_like(counts)
    cl.enqueue_copy(queue, firsts, out)
    assert total == counts.sum()
    np.testing.assert_array_equal(firsts, np.concatenate([[0], np.cumsum(counts)[:-1]]))
