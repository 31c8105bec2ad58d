import json, glob, re, statistics, sys
d = sys.argv[1]
T = ["pt_naive","pt_inplace_regen","pt_compact_regen","bdpt_naive_connect","bdpt_parallel_connect","mlt"]
def cpu(path):
    out = {}
    for line in open(path):
        m = re.match(r"^(\w+)\s+([\d,]+)\s", line)
        if m and m.group(1) in T: out[m.group(1)] = int(m.group(2).replace(",", ""))
    return out
rows = {}
for side in ("before", "main"):
    rows[("cpu", side)] = [cpu(p) for p in sorted(glob.glob(f"{d}/cpu_{side}_*.txt"))]
    rows[("gpu", side)] = [json.loads(open(p).read().strip().splitlines()[-1]) for p in sorted(glob.glob(f"{d}/gpu_{side}_*.json"))]
print("| technique | CPU's sizes, before | main | ratio of medians | GPU's sizes, before | main | ratio of medians |")
print("|---|---|---|---:|---|---|---:|")
for t in T:
    cells = []
    for size in ("cpu", "gpu"):
        b = [r[t] / 1000 for r in rows[(size, "before")]]; m = [r[t] / 1000 for r in rows[(size, "main")]]
        cells += [", ".join(f"{x:,.0f}" for x in b), ", ".join(f"{x:,.0f}" for x in m), f"{statistics.median(m)/statistics.median(b):.2f}x"]
    print(f"| {t} | " + " | ".join(cells) + " |")
