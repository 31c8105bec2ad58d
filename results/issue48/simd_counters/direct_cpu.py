"""Host CPU time (time.thread_time of the driving thread) of whole renders, counters off and on,
interleaved, min of repeats: a check of the host meter's differences, which load makes noisy."""
import json, sys, time
from toolkit.api import render
from toolkit.measure.host_meter import GPU_SIZES, sized_options, spp_of, GROWTH
gpu = sys.argv[1] == "gpu"
techniques = sys.argv[2].split(",")
out = {}
for t in techniques:
    opts = dict(resolution=(256, 256), technique_options=sized_options(t, gpu), progress=False)
    spp = GROWTH * spp_of(t, 16)
    for cs in (False, True):
        render("scenes/cornell_box", t, spp=1, resolution=(16, 16), count_simd=cs, technique_options=opts["technique_options"])
    best = {False: 1e9, True: 1e9}
    for rep in range(2):
        for cs in (False, True):
            start = time.thread_time()
            r = render("scenes/cornell_box", t, spp=spp, count_simd=cs, **opts)
            best[cs] = min(best[cs], time.thread_time() - start)
    samples = 256 * 256 * spp
    out[t] = {"spp": spp, "off_ns": best[False] / samples * 1e9, "on_ns": best[True] / samples * 1e9}
    print(f"| {t} | {spp} | {out[t]['off_ns']:.1f} | {out[t]['on_ns']:.1f} | {best[True] / best[False]:.2f}x |", flush=True)
print(json.dumps(out))
