"""Counted and plain host-meter pairs, interleaved (plain, counted, plain, ...), per technique."""
import json, sys
from toolkit.measure.host_meter import host_meter, median_of_pairs
techniques = sys.argv[1].split(","); rounds = int(sys.argv[2]); out = sys.argv[3]
report = {}
for t in techniques:
    pairs = {False: [], True: []}
    for r in range(rounds):
        for counted in (False, True):
            rep = host_meter(techniques=[t], gpu_sizes=True, count_simd=counted, repeats=1, warm_up_full=(r == 0))
            row = rep["techniques"][t]
            pairs[counted].append({k: v for k, v in row.items() if isinstance(v, (int, float))})
    report[t] = {("counted" if c else "plain"): {"median": median_of_pairs(p), "pairs": p} for c, p in pairs.items()}
    m = {c: report[t][c]["median"] for c in ("plain", "counted")}
    print(t, {c: (round(m[c]["host_cpu_ns_per_sample"], 2), [round(x, 2) for x in m[c]["interval"]["host_cpu_ns_per_sample"]],
                  round(m[c]["pass_cpu_ns_per_sample"], 2)) for c in m},
          "ratio", round(m["counted"]["host_cpu_ns_per_sample"] / m["plain"]["host_cpu_ns_per_sample"], 2),
          "pass ratio", round(m["counted"]["pass_cpu_ns_per_sample"] / m["plain"]["pass_cpu_ns_per_sample"], 2), flush=True)
    json.dump(report, open(out, "w"))
