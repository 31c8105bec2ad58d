import sys, time
import pyopencl as cl
from toolkit.opencl import program, kernel_times
from toolkit.techniques import kernels as kmod
from toolkit.api import as_scene, render
from toolkit.measure.host_meter import sized_options, RESOLUTION
T = time.thread_time_ns
acc = {}
def add(k, dt, n=1):
    e = acc.setdefault(k, [0, 0]); e[0] += n; e[1] += dt
P = program
def launch(queue, kernel, n, *args, local_size=P.LOCAL_SIZE):
    t0 = T()
    launched = queue.builds.launched
    state = launched.get(kernel.int_ptr)
    if state is None or state.kernel is not kernel:
        P.check_work_group(kernel.function_name, local_size, P._work_group_limit(kernel, queue.device), queue.device.name.strip())
        state = launched[kernel.int_ptr] = P._Launched(kernel)
    tA = T(); add("lookup", tA - t0)
    values = state.values
    by_identity = state.by_identity
    sa = 0; nsa = 0
    for i, value in enumerate(args):
        previous = values[i]
        if value is previous and by_identity[i]:
            continue
        fingerprint = P._fingerprint(value)
        if not P._same_fingerprint(state.fingerprints[i], fingerprint):
            s = T(); P._set_arg(state.own, i, value); sa += T() - s; nsa += 1
            state.fingerprints[i] = fingerprint
        if value is not previous:
            values[i], by_identity[i] = value, P._kept_by_identity(value)
    t1 = T(); add("argloop(incl set_arg)", t1 - tA); add("nargs", len(args))
    event = cl.enqueue_nd_range_kernel(queue, state.own, (P.padded(n, local_size),), (local_size,))
    t2 = T()
    tag = "full" if n >= 270000 else "drain"; add("python(excl set_arg) "+tag, t1 - t0 - sa); add("set_arg", sa, nsa); add("enqueue "+tag, t2 - t1)
    return event
program.launch = launch
real_kl = kmod.Kernels.launch
def klaunch(self, *a, **k):
    t = T(); r = real_kl(self, *a, **k); t2 = T()
    add("Kernels.launch total", t2 - t); 
    s = T(); del r; add("event release", T() - s)
    return None
kmod.Kernels.launch = klaunch
import gc
_gs = {}
def cb(phase, info):
    if phase == "start": _gs['t'] = T()
    else: add(f"gc gen{info['generation']}", T() - _gs['t'])
gc.callbacks.append(cb)
import os
if os.environ.get("FREEZE"): gc.freeze()
tech = sys.argv[1]
scene = as_scene("cornell_box")
to = sized_options(tech, True)
render(scene, tech, technique_options=to, resolution=(16,16), spp=1)
res = {}
for spp in map(int, sys.argv[2:]):
    acc.clear(); t = T()
    render(scene, tech, technique_options=to, resolution=RESOLUTION, spp=spp)
    res[spp] = (T() - t, {k: tuple(v) for k, v in acc.items()})
a, b = sorted(res)
print(tech, "total diff ms", (res[b][0]-res[a][0])/1e6)
for k in res[b][1]:
    n1, t1 = res[a][1].get(k, (0, 0)); n2, t2 = res[b][1][k]
    print(f"{k:28s} calls +{n2-n1:6d}  thread +{(t2-t1)/1e6:.2f}ms  per call {(t2-t1)/1e3/max(1,n2-n1):.1f} us   (4N: {n2} calls {t2/1e3/max(1,n2):.1f} us each)")
