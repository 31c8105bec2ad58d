"""Per-kernel times of repeated renders at the GPU's sizes in one process (issue 48 check 4, results/issue48_model_inputs.md):
PYTHONPATH=. python results/issue48/model_inputs/fixed.py TECH spp spp ...; CPU_SIZES=1 for the device's own sizes; run D used
POCL_CACHE_DIR=<an empty folder>. Writes /tmp/hm/fixed_TECH_spps.json."""
import sys, time, resource, json
from toolkit.api import as_scene, render
from toolkit.measure.host_meter import sized_options, RESOLUTION
tech = sys.argv[1]
spps = [int(s) for s in sys.argv[2:]]
scene = as_scene("cornell_box")
import os
to = sized_options(tech, not os.environ.get("CPU_SIZES"))
t0 = time.time()
render(scene, tech, technique_options=to, resolution=(16, 16), spp=1)
print("warm-up", round(time.time() - t0, 2), "s", flush=True)
out = []
for spp in spps:
    f0 = resource.getrusage(resource.RUSAGE_SELF)
    t, c = time.time(), time.thread_time()
    r = render(scene, tech, technique_options=to, resolution=RESOLUTION, spp=spp, time_phases=True)
    wall, cpu = time.time() - t, time.thread_time() - c
    f1 = resource.getrusage(resource.RUSAGE_SELF)
    kt = r.stats["kernel_times"]
    ks = sum(v["seconds"] for v in kt.values())
    print(f"spp {spp}: wall {wall:.2f} s thread {cpu:.2f} s kernels {ks:.2f} s  minflt {f1.ru_minflt-f0.ru_minflt} "
          f"proc user {f1.ru_utime-f0.ru_utime:.2f} sys {f1.ru_stime-f0.ru_stime:.2f} maxrss {f1.ru_maxrss//1024} MB", flush=True)
    for k, v in kt.items():
        print(f"   {k:28s} {v['launches']:6d} {v['seconds']:8.3f}")
    out.append({"spp": spp, "wall": wall, "thread": cpu, "kernels": kt, "minflt": f1.ru_minflt - f0.ru_minflt,
                "sys": f1.ru_stime - f0.ru_stime, "user": f1.ru_utime - f0.ru_utime})
json.dump(out, open(f"/tmp/hm/fixed_{tech}_{'_'.join(map(str, spps))}.json", "w"), indent=1)
