"""Where the study's renders run: here, one after the other, or on a Dask cluster
(`study --scheduler`). A worker gets a Repetition (names and numbers), loads the scene once, builds
its kernels once with an untimed warm-up, and sends back the image with its render time. The
scene goes as an absolute path with the digest of the scene the study loaded (`scene_digest`),
so that a worker renders the scene the user sees, in whatever folder it runs."""
import dataclasses
import hashlib
import sys

import numpy as np
from tqdm.auto import tqdm

from toolkit.api import render
from toolkit.core.scene import load_scene
from toolkit.core.validate import InputError

_scenes = {}      # per process: scene path -> (its digest, the Scene): a worker loads each scene once
_warm = set()     # per process: runs whose kernels are built and launched once


def scene_digest(scene):
    """A hash of everything a render reads from a scene (geometry, materials, camera, integrator
    settings, reference): what the study saw when it started, shipped with each repetition."""
    digest = hashlib.sha256()
    for array in (scene.vertices, scene.triangles, scene.material_of, scene.emission_of,
                  scene.reference, scene.reference_stderr):
        digest.update(b"-" if array is None else np.ascontiguousarray(array).tobytes())
    with np.printoptions(floatmode="unique", threshold=sys.maxsize):     # every digit of every number
        digest.update(repr((scene.name, scene.camera, scene.materials, scene.max_depth, scene.rr_depth,
                            scene.clamp)).encode())
    return digest.hexdigest()


def _scene_of(job):
    """The Scene of a repetition. A path (absolute: a worker's own folder is not the user's) is
    loaded once per process and version: a scene edited between two studies in one process (a
    notebook, a Dask worker) is read again, and a scene that differs from the one the study
    started with is an error, not another scene's numbers."""
    scene = job.scene
    if isinstance(scene, str):
        digest, loaded = _scenes.get(scene, (None, None))
        if digest != job.scene_digest:
            loaded = load_scene(scene)
            digest = scene_digest(loaded)
            if job.scene_digest is not None and digest != job.scene_digest:
                raise InputError(f"{scene}: the scene here differs from the one the study started with "
                                 "(edited since, or another file on this worker); run the study again")
            _scenes[scene] = digest, loaded
        scene = loaded
    if job.run.integrator:
        scene = dataclasses.replace(scene, **dict(job.run.integrator))
    return scene


def render_job(job, spp, seed):
    """Render `job`'s run with `spp` samples and `seed`, after a warm-up the first time in this process."""
    scene = _scene_of(job)
    run = job.run
    settings = dict(technique=run.technique, resolution=run.resolution, device=job.device, count_simd=False,
                    options=dict(run.options), bvh=job.bvh)
    key = (job.scene if isinstance(job.scene, str) else id(job.scene), job.scene_digest, run, job.device, job.bvh)
    if key not in _warm:
        # Warm-up, untimed: the kernel build and the first launches (PoCL compiles there).
        render(scene, spp=1, seed=seed, **settings)
        _warm.add(key)
    return render(scene, spp=spp, seed=seed, **settings)


def run_repetition(job):
    """Render one repetition: {"image" (H, W, 3) float64, "stderr" (its own standard error, from its
    samples or passes), "dof" (None: from samples), "seconds" (render only), "device"}."""
    result = render_job(job, job.spp, job.seed)
    return {"image": result.image, "stderr": result.stderr, "dof": result.stats["degrees_of_freedom"],
            "seconds": result.stats["seconds"], "device": result.stats["device"]}


def map_jobs(function, items, scheduler, progress, what):
    """function(*item) for every item: here, in order, or on the Dask cluster at `scheduler`."""
    if scheduler is None:
        bar = tqdm(total=len(items), desc=what, unit="render", file=sys.stderr, leave=False, disable=not progress)
        out = []
        for item in items:
            out.append(function(*item))
            bar.update(1)
        bar.close()
        return out
    try:
        # Optional: dask.distributed is the [cluster] extra, needed only with a scheduler.
        from distributed import Client, progress as dask_progress
    except ImportError:
        raise InputError('--scheduler needs dask.distributed: pip install ".[cluster]"') from None
    with Client(scheduler) as client:       # an address, or a cluster object from Python
        futures = [client.submit(function, *item, pure=False) for item in items]
        if progress:
            dask_progress(futures)
        return client.gather(futures)
