"""Why program.launch costs more inside a render: the same launch timed quiet, with the caches
evicted before it, and while the device's worker threads run a heavy kernel."""
import time, sys
import numpy as np, pyopencl as cl
from toolkit.opencl import program
from toolkit.opencl.device import get_queue
T = time.thread_time_ns
q = get_queue() if callable(get_queue) else None
ctx = q.context
src = """
__kernel void busy(__global float *a, int n) { int g = get_global_id(0); float x = a[g];
  for (int i = 0; i < n; ++i) x = x * 1.0000001f + 0.5f; a[g] = x; }
__kernel void small(""" + ", ".join(f"__global int *b{i}" for i in range(14)) + ", " + ", ".join(f"int n{i}" for i in range(6)) + """) {
  if (get_global_id(0) == 0) b0[0] = n0; }
"""
from toolkit.opencl.builds import BuiltProgram
prg = BuiltProgram(ctx, src).build()
busy, small = cl.Kernel(prg, "busy"), cl.Kernel(prg, "small")
bufs = [cl.Buffer(ctx, cl.mem_flags.READ_WRITE, 4096) for _ in range(14)]
ints = [np.int32(i) for i in range(6)]
big = cl.Buffer(ctx, cl.mem_flags.READ_WRITE, 4 * 65536)
evict = np.zeros(64 << 20, np.uint8)
def one(k):   # one step's argument pattern: two buffers swap, the rest as before
    args = list(bufs); 
    if k % 2: args[1], args[2] = args[2], args[1]
    return args + ints
res = {}
for mode in ("quiet", "evicted", "busy", "quiet"):
    t_launch = []
    for k in range(300):
        if mode == "evicted": evict[::64] += 1
        if mode == "busy" and k % 20 == 0:
            q.finish(); busy.set_args(big, np.int32(20000)); cl.enqueue_nd_range_kernel(q, busy, (65536,), (64,))
        a = one(k)
        t = T(); program.launch(q, small, 1, *a, local_size=64); t_launch.append(T() - t)
        if mode != "busy": q.finish()
    q.finish()
    print(f"{mode:8s} program.launch median {np.median(t_launch)/1e3:6.1f} us  mean {np.mean(t_launch)/1e3:6.1f} us")
