"""Where the study's renders run: here, one after the other, or on a Dask cluster
(`study --scheduler`). A worker gets a Repetition (names and numbers), loads the scene once, builds
its kernels once with an untimed warm-up, and sends back the image with its render time."""
import dataclasses
import sys

from tqdm.auto import tqdm

from toolkit.api import render
from toolkit.core.scene import load_scene
from toolkit.core.validate import InputError

_scenes = {}      # per process: a worker loads each scene once
_warm = set()     # per process: runs whose kernels are built and launched once


def _scene_of(job):
    scene = job.scene
    if isinstance(scene, str):
        if scene not in _scenes:
            _scenes[scene] = load_scene(scene)
        scene = _scenes[scene]
    if job.run.integrator:
        scene = dataclasses.replace(scene, **dict(job.run.integrator))
    return scene


def render_job(job, spp, seed):
    """Render `job`'s run with `spp` samples and `seed`, after a warm-up the first time in this process."""
    scene = _scene_of(job)
    run = job.run
    settings = dict(technique=run.technique, resolution=run.resolution, device=job.device, count_simd=False,
                    options=dict(run.options), bvh=job.bvh)
    key = (job.scene if isinstance(job.scene, str) else id(job.scene), run, job.device, job.bvh)
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
