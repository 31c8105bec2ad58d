"""A technique's kernels: its program, built for the scene, and how they are launched (on its
queue, in work-groups of its local size, with the scene's arguments). This is all that the BDPT
evaluator and the connect phases need of a technique to run a kernel."""
from toolkit.core.layout import SCENE_PARAM_NAMES
from toolkit.opencl import program


class Kernels:
    def __init__(self, queue, built_program, local_size, device_scene):
        self.queue = queue
        self.program = built_program
        self.local_size = local_size      # the program's LOCAL_SIZE: every launch uses it
        self.scene = device_scene

    def kernel(self, name):
        """The kernel object, retrieved once (each retrieval makes a new cl.Kernel)."""
        return program.kernel(self.program, name)

    def launch(self, kernel, n, /, *args, **named):
        """program.launch of `kernel` (a kernel object or its name) over n work-items. Arguments given
        by name follow the positional ones: the names are the kernel's own parameter names, in its
        order (tests/test_kernel_args.py checks them)."""
        if isinstance(kernel, str):
            kernel = self.kernel(kernel)
        return program.launch(self.queue, kernel, n, *args, *named.values(), local_size=self.local_size)

    def scene_args(self):
        """The scene's kernel arguments (SCENE_PARAMS) by parameter name, for launch(**...)."""
        return dict(zip(SCENE_PARAM_NAMES, self.scene.args()))
