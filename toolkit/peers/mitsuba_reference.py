"""A scene's reference image rendered by Mitsuba 3 (scenes/FORMAT.md: reference.exr, its
standard error reference_stderr.exr, and reference.json saying how it was made):

    python -m toolkit.peers.mitsuba_reference scenes/door_ajar --integrator ptracer --spp 4096 --passes 32

The standard error comes from the spread of `passes` independent renders (seeds 0, 1, ...),
each of `spp` samples per pixel. `path` is the integrator the shared scenes' references were
made with. `ptracer` (Mitsuba's light tracer) is for scenes whose light reaches the camera's room
only through a narrow opening, where a path tracer's eye paths rarely pass it: on door_ajar,
light tracing's variance per second is ~90x lower (measured when the scene was made, commit
de7443a; results/issue40_mlt_door.md). Each pass's image is kept in
`<folder>/reference_passes.npz` as it comes, so a long run that is stopped loses nothing:
`--resume` carries on from there.
"""
import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from toolkit.api import as_scene
from toolkit.core.images import write_image
from toolkit.peers.mitsuba import INTEGRATORS, MitsubaRenderer


def render_reference(scene, integrator="path", spp=1024, passes=32, resume=False, progress=print):
    """Render `passes` x `spp` samples per pixel with Mitsuba into the scene's folder; returns
    reference.json's dict."""
    scene = as_scene(scene)
    folder = scene.path.parent if scene.path.is_file() else scene.path
    peer = MitsubaRenderer(scene, integrator=integrator)
    peer.mi.set_log_level(peer.mi.LogLevel.Warn)     # no progress bar per pass in a long log
    saved = folder / "reference_passes.npz"
    images, seconds = [], 0.0
    if resume and saved.exists():
        with np.load(saved) as old:
            if int(old["spp"]) != spp or str(old["integrator"]) != integrator:
                raise ValueError(f"{saved} holds passes of another spp or integrator; remove it or match them")
            images, seconds = list(old["images"]), float(old["seconds"])
    while len(images) < passes:
        image, s = peer.render(spp, seed=len(images))
        images.append(image)
        seconds += s
        np.savez(saved, images=np.array(images), seconds=seconds, spp=spp, integrator=integrator)
        if progress:
            progress(f"pass {len(images)}/{passes}: {s:.1f} s, image mean {image.mean():.5f}")
    stack = np.array(images)
    mean = stack.mean(0)
    stderr = stack.std(0, ddof=1) / np.sqrt(passes)
    if not (np.isfinite(mean).all() and np.isfinite(stderr).all()):
        raise ValueError("Mitsuba returned NaN or infinite pixels: no reference written")
    info = describe(peer, spp, passes, seconds, mean, stderr)
    write_image(folder / "reference.exr", mean)
    write_image(folder / "reference_stderr.exr", stderr)
    for preview in ("reference.png", "reference_stderr.png"):    # write_image's sRGB previews: not data
        (folder / preview).unlink(missing_ok=True)
    (folder / "reference.json").write_text(json.dumps(info, indent=2) + "\n")
    saved.unlink()
    return info


def describe(peer, spp, passes, seconds, mean, stderr):
    """reference.json as scenes/FORMAT.md describes it."""
    import mitsuba
    y, y_err = mean.mean(-1), stderr.mean(-1)
    lit = y > 0
    rel = y_err[lit] / y[lit]
    rel_rgb = [float((stderr[..., c][mean[..., c] > 0] / mean[..., c][mean[..., c] > 0]).mean()) for c in range(3)]
    whole = float(np.sqrt((y_err ** 2).sum()) / y.sum()) if y.sum() > 0 else None
    return {"renderer": "mitsuba", "version": mitsuba.__version__, "variant": peer.variant,
            "integrator": {k: v for k, v in peer.integrator.items()},
            "sampler": "independent", "rfilter": "box",
            "converter": "toolkit-scene/1 to Mitsuba 3 scene dict as FORMAT.md specifies (toolkit/peers/mitsuba.py)",
            "spp": spp * passes, "passes": passes, "seconds": round(seconds, 1),
            "mean_rgb": mean.reshape(-1, 3).mean(0).tolist(),
            "mean_rel_stderr": float(rel.mean()), "median_rel_stderr": float(np.median(rel)),
            "max_rel_stderr": float(rel.max()), "mean_rel_stderr_rgb": rel_rgb,
            "rel_stderr_of_image_mean": whole, "black_pixels": int((~lit).sum()),
            "stderr_image": "reference_stderr.exr"}


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m toolkit.peers.mitsuba_reference", description=__doc__.split("\n\n")[0])
    p.add_argument("scene", help="scene folder or scene.json")
    p.add_argument("--integrator", choices=INTEGRATORS, default="path")
    p.add_argument("--spp", type=int, default=1024, help="samples per pixel of one pass")
    p.add_argument("--passes", type=int, default=32, help="independent passes (the standard error's)")
    p.add_argument("--resume", action="store_true", help="carry on from reference_passes.npz")
    args = p.parse_args(argv)
    start = time.perf_counter()
    info = render_reference(args.scene, args.integrator, args.spp, args.passes, args.resume)
    print(json.dumps(info, indent=2))
    print(f"{time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
