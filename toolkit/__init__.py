"""A PyOpenCL teaching toolkit for SIMD-efficient Monte Carlo light transport
(after van Antwerpen, HPG 2011). Start with `toolkit.render(...)` or `python -m toolkit`."""
from toolkit.opencl import runtimes  # first: registers pip's OpenCL runtimes before any OpenCL call
from toolkit.opencl import kernel_cache  # before pyopencl's import: how it caches (kernel_cache.py)
from toolkit.api import RenderResult, render
from toolkit.core.scene import Scene, SceneError, load_scene
from toolkit.measure.study import study

__all__ = ["render", "RenderResult", "load_scene", "Scene", "SceneError", "study"]
__version__ = "0.1.0"
