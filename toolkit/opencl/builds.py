"""What the toolkit keeps per OpenCL context, owned by the queues of that context.

`device.get_queue` makes one context per device (and lanes setting) with a `Queue`, an
OpenCL command queue that carries the context's `Builds`:
- the programs built there, each once per source, options and device (program.build);
- the arguments each kernel was last launched with (program.launch sets only those that changed);
- the SIMD-lanes setting its programs are built with (toolkit/opencl/lanes.py);
- the host-side BVH of each scene geometry uploaded there (device_scene.py);
- a log of every build() call, which api.render and the tests read.
Every Queue of a context shares its Builds (kernel_times.profiling_queue makes the profiling
one), and nothing of it is kept in a module: a new context starts with nothing built. Across
processes, pyopencl's binary cache and PoCL's kernel cache keep compiled code on disk
(kernel_cache.py).
"""
import pyopencl as cl


class Builds:
    """The programs built in one context, the kernels' last arguments, its lanes setting, its BVHs."""

    def __init__(self, lanes_setting=None):
        self.lanes = lanes_setting   # "on", "off", lanes.HARDWARE or None (lanes.setting_for)
        self.programs = {}           # build key (program.build: source, options, device) -> BuiltProgram
        self.launched = {}           # kernel.int_ptr -> what program.launch keeps of its last launch (_Launched)
        self.bvhs = {}               # (scene name, geometry) -> the host BVH (device_scene.py)
        self.log = []                # (name, seconds, found built in this context) per build() call
        self.lanes_log = []          # (name, lanes setting, {kernel: vector width}) per build() call
        self.profiling = None        # the context's queue with profiling on, once made (kernel_times.py)

    def vector_widths_since(self, mark):
        """{kernel: width} of every build() call since len(lanes_log) was `mark` (a render's programs)."""
        merged = {}
        for _, _, widths in self.lanes_log[mark:]:
            merged.update(widths)
        return merged


class Queue(cl.CommandQueue):
    """An OpenCL command queue that carries its context's Builds (and, while a KernelTimes records
    its launches, that recording: kernel_times.py)."""

    def __init__(self, context, builds, properties=0):
        super().__init__(context, properties=properties)
        # The Context object lives as long as its queue: Intel's runtime invalidates a context whose
        # last Python reference is gone although a queue still holds it (queue.context then fails).
        self.context_kept = context
        self.builds = builds
        self.recording = None


class BuiltProgram(cl.Program):
    """A program that program.build made: its kernels, each retrieved once (each retrieval makes a
    new cl.Kernel), and the work-items per vector the compiler reported for them."""

    def __init__(self, context, source):
        super().__init__(context, source)
        self.kernels_by_name = {}
        self.vector_widths = {}
