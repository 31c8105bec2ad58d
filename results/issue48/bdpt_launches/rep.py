"""Host thread CPU time of renders at the GPU's sizes, N and 4N spp, repeated R times (each after a
small warm-up render, as the host meter does); prints per-repeat differences per sample and their mean
and standard error."""
import sys, time, statistics
from toolkit.api import as_scene, render
from toolkit.measure.host_meter import sized_options, RESOLUTION
tech, n, reps = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
cs = len(sys.argv) > 4 and sys.argv[4] == "simd"
scene = as_scene("cornell_box")
to = sized_options(tech, True)
def timed(spp):
    render(scene, tech, technique_options=to, resolution=(16, 16), spp=1, count_simd=cs)
    t = time.thread_time()
    render(scene, tech, technique_options=to, resolution=RESOLUTION, spp=spp, count_simd=cs)
    return time.thread_time() - t
timed(n)
samples = 3 * n * RESOLUTION[0] * RESOLUTION[1]
diffs = []
for r in range(reps):
    a = timed(n); b = timed(4 * n)
    diffs.append(1e9 * (b - a) / samples)
    print(f"  {tech} {'counted' if cs else 'plain'} N {1e3*a:.1f} ms, 4N {1e3*b:.1f} ms, diff {diffs[-1]:.2f} ns/sample", flush=True)
m = statistics.mean(diffs); se = statistics.stdev(diffs) / len(diffs) ** 0.5
print(f"{tech} {'counted' if cs else 'plain'}: {m:.2f} +- {se:.2f} ns/sample (mean of {reps} differences, standard error)")
