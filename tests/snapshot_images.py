"""Render every technique on both bundled scenes at a fixed seed and small size, and save or
compare the images, so that a refactor can prove it leaves every image bit-identical.

    python tests/snapshot_images.py save /tmp/wt9_before     # before the change
    python tests/snapshot_images.py check /tmp/wt9_before    # after it: exit 1 on any difference
"""
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import toolkit  # noqa: E402

TECHNIQUES = ["pt_naive", "pt_inplace_regen", "pt_compact_regen", "bdpt_naive_connect",
              "bdpt_parallel_connect"]
SCENES = ["cornell_box", "cornell_spheres"]
SPP = {"pt": 8, "bdpt": 2}


def renders():
    for scene in SCENES:
        for technique in TECHNIQUES:
            spp = SPP[technique.split("_")[0]]
            for count_simd in (True, False):
                result = toolkit.render(ROOT / "scenes" / scene, technique=technique, spp=spp, seed=7,
                                        resolution=(16, 16), count_simd=count_simd)
                yield f"{scene}_{technique}_{'counted' if count_simd else 'plain'}", result


def main(mode, folder):
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    differ = []
    for name, result in renders():
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
    main(*sys.argv[1:3])
