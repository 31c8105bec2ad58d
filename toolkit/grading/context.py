"""What a check works with: the device queue, the folder holding the submission, the bundled
scenes on the device, and the techniques built from the submission or from the toolkit's files.
A build from the submission finds its files through sources() (sources.py: what it may include),
a build from the toolkit's files through reference_sources() (stubs.py: the reference solution is
refused where it is a stub, in the student edition)."""
import numpy as np
import pyopencl as cl

from toolkit.core.scene import bundled_scene_dir, load_scene
from toolkit.grading.sources import SubmissionSources
from toolkit.grading.stubs import CourseSources
from toolkit.opencl import program
from toolkit.opencl.device import get_queue
from toolkit.opencl.device_scene import DeviceScene


class Context:
    """What a check works with: the device queue and the folder holding the submission."""

    def __init__(self, folder, assignment, device=None, shown="compact.h", checks=None, inputs=0):
        self.folder = folder
        self.assignment = assignment
        self.shown = shown   # the name of the student's file, for messages
        self.checks = None if checks is None else set(checks)   # what this worker runs (None: all)
        self.inputs = inputs   # 0: the public inputs, the ones a student sees; else hidden ones (rng, seed)
        self.queue = get_queue(device)
        self._scenes = {}

    def rng(self, public):
        """The random generator of a check's inputs: seeded with `public`, as the student's copy
        runs it, or, for the instructor's hidden inputs, with `public` and this run's `inputs`
        together, so that each check still draws inputs of its own."""
        return np.random.default_rng(public if self.inputs == 0 else [public, self.inputs])

    def seed(self, public):
        """A render's seed: `public`, or one drawn from it and the hidden `inputs` (see rng)."""
        return public if self.inputs == 0 else int(self.rng(public).integers(1, 2**31))

    def runs(self, *names):
        """Whether any of the checks `names` runs here: the build step builds only what they need."""
        return self.checks is None or bool(self.checks.intersection(names))

    def scene(self, name="cornell_box"):
        if name not in self._scenes:
            scene = load_scene(bundled_scene_dir(name))
            self._scenes[name] = (scene, DeviceScene(self.queue, scene))
        return self._scenes[name]

    def technique(self, cls, student=True, scene="cornell_box", folder=None, **options):
        """An instance of technique `cls` built from the submission (or the toolkit's own files); from
        `folder` (a variant of the submission, beside it) if given. `options`: the technique's own
        (stream_size=256, ...), as toolkit.render passes them."""
        sources = self.sources(folder) if student else self.reference_sources()
        return cls(self.queue, self.scene(scene)[1], sources=sources, **options)

    def build(self, name, defines=None):
        return program.build(self.queue, name, defines, directory=self.sources())

    def sources(self, folder=None):
        """Where a build of the submission (in `folder`, by default the submission's) finds its files."""
        return SubmissionSources(folder or self.folder, self.assignment.replaces, self.assignment.headers)

    def reference_sources(self):
        """Where a build of the toolkit's own files finds them: cl/, refusing the graded file if it
        is a stub (and, in the student edition, always: it is not the reference there). The other
        assignments' stubs build as they are."""
        return CourseSources(refused={self.assignment.replaces})

    def toolkit_source(self, name):
        """The text of the toolkit's cl/<name>, the reference (ReferenceMissing where it is not held)."""
        return self.reference_sources().read(program.cl_dir() / name)

    def buffer(self, array):
        return cl.Buffer(self.queue.context, cl.mem_flags.READ_WRITE | cl.mem_flags.COPY_HOST_PTR,
                         hostbuf=np.ascontiguousarray(array))

    def read(self, buffer, dtype, n, offset=0):
        out = np.empty(n, dtype)
        if n:
            cl.enqueue_copy(self.queue, out, buffer, src_offset=offset)
        return out
