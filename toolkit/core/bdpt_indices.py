"""The index arithmetic of BDPT's connect phase, which the host and the kernels share.

Each formula is one Python function (ints or numpy arrays); layout.h gets the same function as a
C helper (c_formula.c_helper, see c_definitions below), so the two cannot disagree.

Strategies of one sample. A sample with n_light light and n_eye eye vertices makes every (s, t)
with 0 <= s <= n_light, 1 <= t <= n_eye except (0, 1), which would need the eye path to hit the
pinhole: connection_count of them, numbered k = 0 .. count - 1 with k + 1 = (t - 1)(n_light + 1) + s
(connection_strategy).

Per-strategy images (render --strategies, toolkit/techniques/strategy_images.py): the strategies
of paths with k = s + t - 1 edges, k = 1 .. max_edges, in order of k, then of s (s = 0 .. k):
strategy_index; strategy_count(max_edges) for all longer paths together.

The plain connect phase's records (cl/bdpt_naive_connect.cl), for `pool` slots of which the
terminated ones write `splats` light-tracing (t = 1) records in all:
    naive_splat_record(first, s)   slot's t = 1 splat of s = 1 .. n_light (first: the scan of the splat counts)
    naive_sum_record(splats, slot) the sum of the slot's eye-path strategies (t >= 2)
    naive_strategy_record(...)     with per-strategy images: one record per eye-path strategy of the
                                   short paths, after all the sums
and naive_record_count of them in all.
"""
from toolkit.core.c_formula import c_helper, where


def connection_count(n_light, n_eye):
    """Strategies (s, t) of a sample with n_light light and n_eye eye vertices."""
    return (n_light + 1) * n_eye - 1


def connection_strategy(k, n_light):
    """(s, t) of connection k of a sample with n_light light vertices."""
    return (k + 1) % (n_light + 1), (k + 1) // (n_light + 1) + 1


def strategy_count(max_edges):
    """Per-strategy images: strategies of paths with 1 .. max_edges edges (k + 1 each)."""
    return max_edges * (max_edges + 3) // 2


def strategy_index(s, t, max_edges):
    """Per-strategy images: the index of strategy (s, t), by path edges k = s + t - 1, then by s."""
    k = s + t - 1
    return where(k <= max_edges, (k - 1) * (k + 2) // 2 + s, strategy_count(max_edges))


def naive_splat_record(first, s):
    """Plain connect: the record of a slot's light-tracing strategy (s, 1), its splats starting at `first`."""
    return first + s - 1


def naive_sum_record(splats, slot):
    """Plain connect: the record of the sum of a slot's eye-path strategies."""
    return splats + slot


def naive_strategy_record(splats, pool, slot, strategy, count):
    """Plain connect, per-strategy images: the record of eye-path strategy `strategy` (of `count`) of a slot."""
    return splats + pool + slot * count + strategy


def naive_record_count(splats, pool, count):
    """Plain connect: records in all (count: strategies with a record each, 0 without per-strategy images)."""
    return splats + pool + pool * count


def c_definitions():
    ints = lambda *names: [(n, "int") for n in names]
    return "\n".join([
        c_helper(connection_count, ints("n_light", "n_eye")),
        c_helper(connection_strategy, ints("k", "n_light"), outputs=ints("s", "t")),
        c_helper(strategy_count, ints("max_edges")),
        c_helper(strategy_index, ints("s", "t", "max_edges")),
        c_helper(naive_splat_record, ints("first", "s")),
        c_helper(naive_sum_record, ints("splats", "slot")),
        c_helper(naive_strategy_record, ints("splats", "pool", "slot", "strategy", "count")),
        c_helper(naive_record_count, ints("splats", "pool", "count"))])
