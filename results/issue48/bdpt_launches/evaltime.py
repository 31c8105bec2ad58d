"""Host thread CPU time inside BdptEvaluator.evaluate (the pass's loop: walk, list, connect,
regenerate), for renders at the GPU's sizes at N and 4N spp, repeated: what 3N more samples cost
the loop alone, without the render's fixed costs (technique, buffers, film)."""
import sys, time, statistics
from toolkit.api import as_scene, render
from toolkit.measure.host_meter import sized_options, RESOLUTION
from toolkit.techniques import bdpt_evaluator
tech, n, reps = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
cs = len(sys.argv) > 4 and sys.argv[4] == "simd"
spent = [0.0]
real = bdpt_evaluator.BdptEvaluator.evaluate
def evaluate(self, p, sink):
    t = time.thread_time()
    try:
        return real(self, p, sink)
    finally:
        spent[0] += time.thread_time() - t
bdpt_evaluator.BdptEvaluator.evaluate = evaluate
scene = as_scene("cornell_box")
to = sized_options(tech, True)
def timed(spp):
    render(scene, tech, technique_options=to, resolution=(16, 16), spp=1, count_simd=cs)
    spent[0] = 0.0
    render(scene, tech, technique_options=to, resolution=RESOLUTION, spp=spp, count_simd=cs)
    return spent[0]
timed(n)
samples = 3 * n * RESOLUTION[0] * RESOLUTION[1]
diffs = []
for r in range(reps):
    a = timed(n); b = timed(4 * n)
    diffs.append(1e9 * (b - a) / samples)
    print(f"  {tech} {'counted' if cs else 'plain'} evaluate N {1e3*a:.1f} ms, 4N {1e3*b:.1f} ms, diff {diffs[-1]:.2f} ns/sample", flush=True)
m = statistics.mean(diffs); se = statistics.stdev(diffs) / len(diffs) ** 0.5
print(f"{tech} {'counted' if cs else 'plain'} evaluate: {m:.2f} +- {se:.2f} ns/sample (mean of {reps} differences, standard error)")
