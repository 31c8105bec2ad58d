"""Where an mlt render's time goes at bench's CPU sizes: the start (begin) against the iterations."""
import os, sys, time
from toolkit.api import as_scene, render
import toolkit.techniques.mlt as mlt
scene = as_scene(os.path.join(os.getcwd(), "scenes", "cornell_box"))
times = {}
orig_begin = mlt.Mlt.begin if hasattr(mlt, "Mlt") else None
cls = [v for v in vars(mlt).values() if isinstance(v, type) and hasattr(v, "begin") and v.__module__ == mlt.__name__][0]
ob = cls.begin
def begin(self, *a, **k):
    t = time.perf_counter(); c = ob(self, *a, **k); self.queue.finish(); times.setdefault("start", []).append(time.perf_counter() - t); return c
cls.begin = begin
for tech in sys.argv[1].split(","):
    render(scene, tech, resolution=(16, 16), spp=1)
    for rep in range(3):
        times.clear()
        t = time.perf_counter()
        render(scene, tech, resolution=(128, 128), spp=2)
        print(tech, "total %.3f s, start %.3f s" % (time.perf_counter() - t, sum(times.get("start", [0]))))
