"""What a pass's drain costs the host: the meter at the GPU's sizes with every render in one pass (pass_spp 64)."""
import json, sys
from toolkit.measure.host_meter import host_meter
from toolkit.api import RenderOptions
techs = sys.argv[1].split(",")
r = host_meter("cornell_box", techniques=techs, gpu_sizes=True, repeats=int(sys.argv[2]), technique_options={"pass_spp": int(sys.argv[3])})
for t, row in r["techniques"].items():
    print(t, "host %.1f ns/sample, spread %s, launches/M %.1f, launches/pass %.1f" % (row["host_cpu_ns_per_sample"], row["spread"]["host_cpu_ns_per_sample"], row["launches_per_million"], row.get("launches_per_pass", -1)))
