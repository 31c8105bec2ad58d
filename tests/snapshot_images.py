"""Render every technique on both bundled scenes at a fixed seed and small size, and save or
compare the images, so that a refactor can prove it leaves every image bit-identical.

    python tests/snapshot_images.py save /tmp/wt9_before     # before the change
    python tests/snapshot_images.py check /tmp/wt9_before    # after it: exit 1 on any difference
    python tests/snapshot_images.py check /tmp/wt9_before pt # only the techniques named pt...
"""
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import toolkit  # noqa: E402

TECHNIQUES = ["pt_naive", "pt_inplace_regen", "pt_compact_regen", "bdpt_naive_connect",
              "bdpt_parallel_connect", "mlt"]
SCENES = ["cornell_box", "cornell_spheres"]
SPP = {"pt": 8, "bdpt": 2, "mlt": 4}
# 100 chains: 1,024 mutations are 11 iterations, the last with 24 chains active, and a pass of
# 256 mutations (one per pixel) ends inside an iteration. start = naive: the default until issue 48
# (now pool), so that images saved before it still compare.
OPTIONS = {"mlt": {"chains": 100, "start": "naive"}}


def renders(only=""):
    for scene in SCENES:
        for technique in (t for t in TECHNIQUES if t.startswith(only)):
            family = technique.split("_")[0]
            spp, options = SPP[family], OPTIONS.get(family)
            for count_simd in (True, False):
                result = toolkit.render(ROOT / "scenes" / scene, technique=technique, spp=spp, seed=7,
                                        resolution=(16, 16), count_simd=count_simd, options=options)
                yield f"{scene}_{technique}_{'counted' if count_simd else 'plain'}", result


def main(mode, folder, only=""):
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    differ = []
    for name, result in renders(only):
        # (traversal efficiency is left out: on a compacted stream it depends on the order in
        # which work-groups reach the compaction's atomic counter, which varies from run to run)
        # (pt_inplace_regen's SIMD efficiency is left out too: its slots take their samples from
        # an atomic counter, so which lanes regenerate in a step varies from run to run, on
        # every commit; its image does not)
        kept = ("walk_efficiency_without_compaction", "connect_efficiency_terminated_packed",
                *(() if "pt_inplace_regen" in name else ("simd_efficiency",)))
        stats = json.dumps({k: result.stats.get(k) for k in kept}, sort_keys=True)
        stats_path = folder / f"{name}_stats.json"
        if mode == "save":
            stats_path.write_text(stats)
        elif stats != stats_path.read_text():
            print(f"DIFFERENT {stats_path.name}: {stats}")
            differ.append(stats_path.name)
        for kind, array in (("image", result.image), ("stderr", result.stderr)):
            path = folder / f"{name}_{kind}.npy"
            if mode == "save":
                np.save(path, array)
            else:
                before = np.load(path)
                same = before.shape == array.shape and before.tobytes() == array.tobytes()
                print(f"{'same' if same else 'DIFFERENT':9} {path.name}")
                if not same:
                    differ.append(path.name)
    if differ:
        sys.exit(f"{len(differ)} images differ: {differ}")


if __name__ == "__main__":
    main(*sys.argv[1:4])
