"""A PyOpenCL teaching toolkit for SIMD-efficient Monte Carlo light transport
(after van Antwerpen, HPG 2011). Start with `toolkit.render(...)` or `python -m toolkit`."""
from toolkit.opencl.runtimes import before_pyopencl_import

# The one step that must come before pyopencl's import, which reads PYOPENCL_NO_CACHE then
# (toolkit/opencl/runtimes.py): it registers nothing; the OpenCL runtimes are registered when a
# device is first asked for. Python runs this file before any module of the package.
before_pyopencl_import()

from toolkit.api import RenderResult, render  # noqa: E402  (after the step above: it imports pyopencl)
from toolkit.core.render_options import RenderOptions  # noqa: E402
from toolkit.core.scene import Scene, SceneError, load_scene  # noqa: E402

__all__ = ["render", "RenderOptions", "RenderResult", "load_scene", "Scene", "SceneError"]
__version__ = "0.1.0"
