"""The host meter's counts for the code an earlier GPU run measured (issue 48, item 5: the model's
validation). The H200's bench (results/gpu.md) ran commit 2221915; today's code reads less back, so
the model is checked against what that commit's host did, measured here on this CPU at the H200
bench's settings: cornell_box 368x368, path tracers 16 spp, BDPT and mlt 2, the H200's stream and
pool sizes (270,336) and chains (262,144), SIMD counters off, one render each after a build.

Run from this checkout, on an export of the commit (`git archive 2221915 | tar -x -C OLD`):
    python results/issue48/meter_at_commit.py OLD results/issue48/host_meter_2221915_h200_bench.json
It imports that commit's toolkit, and this checkout's counter (toolkit/opencl/traffic.py: it needs
only pyopencl) by its path.
"""
import importlib.util
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parents[2]
TECHNIQUES = {"pt_naive": {}, "pt_inplace_regen": {"stream_size": 270_336}, "pt_compact_regen": {"stream_size": 270_336},
              "bdpt_naive_connect": {"pool_size": 270_336}, "bdpt_parallel_connect": {"pool_size": 270_336},
              "mlt": {"pool_size": 270_336, "chains": 262_144}}
RESOLUTION = (368, 368)


def main(old, out):
    sys.path.insert(0, str(Path(old).resolve()))
    spec = importlib.util.spec_from_file_location("traffic", HERE / "toolkit" / "opencl" / "traffic.py")
    traffic = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(traffic)
    from toolkit import api
    from toolkit.techniques import get_technique
    report = {"commit": Path(old).name, "resolution": list(RESOLUTION), "techniques": {}}
    for name, options in TECHNIQUES.items():
        spp = 16 if name.startswith("pt") else 2
        api.render(None, name, spp=1, resolution=(16, 16), options=options, count_simd=False)   # builds
        cls = get_technique(name)[0]
        passes, real = [0], cls.run_pass

        def run_pass(self, *args, **kwargs):
            passes[0] += 1
            return real(self, *args, **kwargs)
        cls.run_pass = run_pass
        try:
            with traffic.Traffic() as counted:
                stats = api.render(None, name, spp=spp, resolution=RESOLUTION, options=options, count_simd=False,
                                   time_phases=True).stats
        finally:
            cls.run_pass = real
        report["techniques"][name] = {
            **counted.figures(), "spp": spp, "seconds": stats["seconds"], "passes": passes[0],
            "kernel_seconds": sum(k["seconds"] for k in stats["kernel_times"].values()),
            "samples": round(stats["samples_per_second"] * stats["seconds"])}
        print(name, json.dumps(report["techniques"][name]), flush=True)
    report["device"] = stats["device"]
    Path(out).write_text(json.dumps(report, indent=1) + "\n")


if __name__ == "__main__":
    main(*sys.argv[1:3])
