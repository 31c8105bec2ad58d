"""Per-render enqueue census: launches by kernel name, fills, copies; and thread CPU time; for renders at N and 4N."""
import sys, time, collections
import pyopencl as cl
from toolkit.opencl import program
from toolkit.api import as_scene, render
from toolkit.measure.host_meter import sized_options, RESOLUTION
acc = collections.Counter()
real_launch = program.launch
def launch(queue, kernel, n, *a, **k):
    acc["launch " + kernel.function_name] += 1
    return real_launch(queue, kernel, n, *a, **k)
program.launch = launch
for name in ["enqueue_copy", "enqueue_fill_buffer"]:
    real = getattr(cl, name)
    def w(*a, _real=real, _name=name, **k):
        acc[_name] += 1
        return _real(*a, **k)
    setattr(cl, name, w)
tech = sys.argv[1]
cs = len(sys.argv) > 4 and sys.argv[4] == "simd"
scene = as_scene("cornell_box")
to = sized_options(tech, True)
render(scene, tech, technique_options=to, resolution=(16, 16), spp=1, count_simd=cs)
res = {}
for spp in map(int, sys.argv[2:4]):
    render(scene, tech, technique_options=to, resolution=(16, 16), spp=1, count_simd=cs)
    acc.clear(); t = time.thread_time()
    render(scene, tech, technique_options=to, resolution=RESOLUTION, spp=spp, count_simd=cs)
    res[spp] = (time.thread_time() - t, dict(acc))
a, b = sorted(res)
samples = (b - a) * RESOLUTION[0] * RESOLUTION[1]
print(tech, f"thread CPU: {res[a][0]:.3f}s, {res[b][0]:.3f}s; diff per sample {1e9*(res[b][0]-res[a][0])/samples:.1f} ns")
for k in sorted(set(res[a][1]) | set(res[b][1])):
    print(f"  {k:40s} {res[a][1].get(k,0):6d} {res[b][1].get(k,0):6d}  diff {res[b][1].get(k,0)-res[a][1].get(k,0):6d}")
