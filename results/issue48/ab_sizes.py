"""Check 3 at the GPU's sizes: samples/s of each technique rendered with GPU_SIZES options, in the
checkout this runs in (PYTHONPATH=checkout). Prints one JSON line {technique: samples/s}."""
import json, os, sys, time
from toolkit.api import as_scene, render
SIZES = {"stream_size": 270_336, "pool_size": 270_336, "chains": 262_144}
SPP = {"mlt/naive": 16, "pt_naive": 16, "pt_inplace_regen": 16, "pt_compact_regen": 16, "bdpt_naive_connect": 16,
       "bdpt_parallel_connect": 16, "mlt": 16}
scene = as_scene(os.path.join(os.getcwd(), "scenes", "cornell_box"))
out = {}
for tech in sys.argv[1].split(","):
    from toolkit.techniques import get_technique
    import inspect
    cls = get_technique(tech)[0]
    takes = set(inspect.signature(cls.__init__).parameters)
    opts = {k: v for k, v in SIZES.items() if k in takes}
    render(scene, tech, technique_options=opts, resolution=(16, 16), spp=1)   # build, unmeasured
    t = time.perf_counter()
    r = render(scene, tech, technique_options=opts, resolution=(256, 256), spp=SPP[tech])
    out[tech] = 256 * 256 * SPP[tech] / (time.perf_counter() - t)
print(json.dumps(out))
