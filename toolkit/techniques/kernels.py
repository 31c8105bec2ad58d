"""A technique's kernels: its program, built for the scene, and how they are launched (on its
queue, in work-groups of its local size, with the scene's arguments). This is all that the BDPT
evaluator and the connect phases need of a technique to run a kernel."""
import numpy as np

from toolkit.core.layout import SCENE_PARAM_NAMES
from toolkit.opencl import program


class Kernels:
    def __init__(self, queue, built_program, local_size, device_scene):
        self.queue = queue
        self.program = built_program
        self.local_size = local_size      # the program's LOCAL_SIZE: every launch uses it
        self.scene = device_scene
        self._scene_args = None   # scene_args, made at its first use: the scene's arguments never change
        self._int32s = {}         # int32's numbers, one object per value

    def kernel(self, name, copy=0):
        """The kernel object, retrieved once per `copy` (program.kernel: a copy per turn of buffers
        that take turns, so that no launch sets an argument)."""
        return program.kernel(self.program, name, copy)

    def launch(self, kernel, n, /, *args, **named):
        """program.launch of `kernel` (a kernel object or its name) over n work-items. Arguments given
        by name follow the positional ones: the names are the kernel's own parameter names, in its
        order (tests/test_kernel_args.py checks them)."""
        if isinstance(kernel, str):
            kernel = self.kernel(kernel)
        return program.launch(self.queue, kernel, n, *args, *named.values(), local_size=self.local_size)

    def scene_args(self):
        """The scene's kernel arguments (SCENE_PARAMS) by parameter name, for launch(**...): the
        same objects at every launch, so program.launch sees at once that they are set."""
        if self._scene_args is None:
            self._scene_args = dict(zip(SCENE_PARAM_NAMES, self.scene.args()))
        return self._scene_args

    def int32(self, value):
        """np.int32(value), the same object for the same value: a launch given the object it was
        given last time knows the argument is set without comparing its bytes (program.launch)."""
        number = self._int32s.get(value)
        if number is None:
            number = self._int32s[value] = np.int32(value)
        return number
