"""The error every bad input raises. A module of its own, importing nothing: the settings
(config.py) are read before pyopencl's import (toolkit/opencl/runtimes.py before_pyopencl_import),
and validate.py, which defines the limits, imports the layouts and with them pyopencl."""


class InputError(ValueError):
    """A bad argument of the command line or of toolkit.render, with the problem named."""
