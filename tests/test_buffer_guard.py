"""Device writes stay inside their buffers: the BDPT techniques (whose vertex and record
buffers are sized from the scene's max_depth) run under a canary guard (tests/buffer_guard.py)
at the edge depths, and the guard itself is shown to catch a write one past the end."""
from dataclasses import replace

import numpy as np
import pyopencl as cl
import pytest

import toolkit
from buffer_guard import BufferGuard


def test_guard_catches_a_write_past_the_end(queue, monkeypatch):
    guard = BufferGuard(monkeypatch)
    n = 16
    buf = cl.Buffer(queue.context, cl.mem_flags.READ_WRITE, 4 * n)
    program = cl.Program(queue.context, "__kernel void poke(__global int* a, int i) { a[i] = 7; }").build()
    poke = cl.Kernel(program, "poke")
    poke(queue, (1,), None, buf, np.int32(n - 1))
    assert guard.check(queue) == []
    poke(queue, (1,), None, buf, np.int32(n))       # one int past the end
    assert len(guard.check(queue)) == 1


@pytest.mark.parametrize("max_depth", [0, 1, 2])
@pytest.mark.parametrize("technique", ["bdpt_naive_connect", "bdpt_parallel_connect"])
def test_bdpt_writes_stay_inside_their_buffers(cornell_box, queue, monkeypatch, technique, max_depth):
    guard = BufferGuard(monkeypatch)
    scene = replace(cornell_box, max_depth=max_depth)
    result = toolkit.render(scene, technique=technique, spp=2, seed=1, resolution=(8, 8))
    assert len(guard.guarded) >= 10          # the guard saw the technique's buffers
    assert guard.check(queue) == []
    assert result.stats["nonfinite_samples"] == 0
    if max_depth == 0:
        assert not result.image.any()        # not even the camera segment: black (FORMAT.md)
    else:
        assert result.image.mean() > 0
