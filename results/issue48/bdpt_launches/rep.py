"""Host thread CPU time of renders at the GPU's sizes, N and 4N spp, repeated R times (each after a
small warm-up render, as the host meter does); prints per-repeat differences per sample and their mean
and standard error. `simd`: SIMD counters on. `evaluate`: only the time inside BdptEvaluator.evaluate
(the pass's loop: walk, list, connect, regenerate), without the render's fixed costs.

    python rep.py TECHNIQUE N REPEATS [simd] [evaluate]

(The host meter now does both: `bench --host --repeats R`, and its pass_cpu_ns_per_sample.)"""
import sys, time, statistics
from toolkit.api import as_scene, render
from toolkit.measure.host_meter import sized_options, RESOLUTION
from toolkit.techniques import bdpt_evaluator
tech, n, reps = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
cs, loop_only = "simd" in sys.argv[4:], "evaluate" in sys.argv[4:]
spent = [0.0]
real = bdpt_evaluator.BdptEvaluator.evaluate
def evaluate(self, p, sink):
    t = time.thread_time()
    try:
        return real(self, p, sink)
    finally:
        spent[0] += time.thread_time() - t
if loop_only:
    bdpt_evaluator.BdptEvaluator.evaluate = evaluate
scene = as_scene("cornell_box")
to = sized_options(tech, True)
def timed(spp):
    render(scene, tech, technique_options=to, resolution=(16, 16), spp=1, count_simd=cs)
    spent[0], t = 0.0, time.thread_time()
    render(scene, tech, technique_options=to, resolution=RESOLUTION, spp=spp, count_simd=cs)
    return spent[0] if loop_only else time.thread_time() - t
timed(n)
samples = 3 * n * RESOLUTION[0] * RESOLUTION[1]
what = f"{tech} {'counted' if cs else 'plain'}{' evaluate' if loop_only else ''}"
diffs = []
for r in range(reps):
    a = timed(n); b = timed(4 * n)
    diffs.append(1e9 * (b - a) / samples)
    print(f"  {what} N {1e3*a:.1f} ms, 4N {1e3*b:.1f} ms, diff {diffs[-1]:.2f} ns/sample", flush=True)
m = statistics.mean(diffs); se = statistics.stdev(diffs) / len(diffs) ** 0.5
print(f"{what}: {m:.2f} +- {se:.2f} ns/sample (mean of {reps} differences, standard error)")
