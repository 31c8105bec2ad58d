"""Renders at the GPU's sizes in one process, each after the meter's small warm-up (issue 48 check 4, run C of results/issue48_model_inputs.md):
PYTHONPATH=. python results/issue48/model_inputs/seq.py TECH:spp ..."""
import sys, time, resource
from toolkit.api import as_scene, render
from toolkit.measure.host_meter import sized_options, RESOLUTION
scene = as_scene("cornell_box")
for arg in sys.argv[1:]:
    tech, spp = arg.split(":"); spp = int(spp)
    to = sized_options(tech, True)
    render(scene, tech, technique_options=to, resolution=(16, 16), spp=1)
    f0 = resource.getrusage(resource.RUSAGE_SELF)
    t, c = time.time(), time.thread_time()
    r = render(scene, tech, technique_options=to, resolution=RESOLUTION, spp=spp, time_phases=True)
    wall, cpu = time.time() - t, time.thread_time() - c
    f1 = resource.getrusage(resource.RUSAGE_SELF)
    kt = r.stats["kernel_times"]
    top = sorted(kt.items(), key=lambda kv: -kv[1]["seconds"])[:3]
    print(f"{tech} spp {spp}: wall {wall:.2f} thread {cpu:.2f} kernels {sum(v['seconds'] for v in kt.values()):.2f} "
          f"minflt {f1.ru_minflt-f0.ru_minflt} user {f1.ru_utime-f0.ru_utime:.2f} sys {f1.ru_stime-f0.ru_stime:.2f} | "
          + ", ".join(f"{k} {v['launches']}x {v['seconds']:.2f}" for k, v in top), flush=True)
