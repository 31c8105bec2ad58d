"""What the toolkit remembers about OpenCL while a process runs, in one object you can see and
reset: the probe's verdicts, the contexts and queues, the kernel cache's problems, and the steps
done once per process (the runtimes' registration, pyopencl's cache switch, this CPU's identity).

Nothing of it lives in a module of its own: each module asks `session()` for the one Session of
this process, made when it is first asked for. (Importing the toolkit asks once, to note whether
pyopencl may keep a cache: runtimes.before_pyopencl_import. It registers nothing: the runtimes
are registered when a device is first asked for.) A test that needs a process's first time again
calls `reset_session()`, or gives a Session of its own with
`monkeypatch.setattr(session_module, "current", Session())`.

What is kept, and why once per process:
- one OpenCL context and queue per device and lanes setting (toolkit/opencl/device.py: get_queue):
  each context holds the programs built there (builds.py), so a second one would build them again;
- the probe's verdict per verdict file (device.py: probe), and where it came from (`devices` says);
- the source text of the toolkit's own programs (program.py: expand_includes), read again when a
  file of it changes: a render builds several programs, and putting each together took milliseconds;
- the kernel cache's problem per folder, and the problems already said (kernel_cache.py);
- the results of the steps that must run once: `runtimes.prepare()` (the loader reads the
  environment once, at the first platform query), `runtimes.before_pyopencl_import()` (pyopencl
  reads PYOPENCL_NO_CACHE once, when it is imported), `probe_cache.cpu_identity()`;
- on Windows, the handles of os.add_dll_directory: the folder stays searched while they live.
"""
import weakref


class Session:
    """The state of the toolkit's OpenCL layer in one process (see the module's docstring)."""

    def __init__(self):
        self.queues = {}              # (device, lanes setting): (context, builds.Queue)
        self.probe_verdicts = {}      # verdict file: (usable, reason)
        self.probe_notes = {}         # verdict file: where the verdict came from (`python -m toolkit devices`)
        self.cache_problems = {}      # kernel cache folder: its problem, or None (usable)
        self.cache_problems_said = set()   # the kernel cache's problems already warned about
        self.dll_directories = []     # os.add_dll_directory's handles (Windows)
        self.done = {}                # a step done once per process: what it returned
        # The toolkit's own programs' source text, put together once (program.py: expand_includes):
        # (cl/ folder, name): (text, the files it read with their stamps, to see a file changed).
        self.expanded_sources = {}
        # Host BVHs (toolkit/opencl/device_scene.py): built before their scene's context (build_ahead)
        # until a DeviceScene takes one, and every one a context holds, so that none is built twice.
        self.built_ahead = {}
        self.held_bvhs = weakref.WeakValueDictionary()
        # `--verbose` (as TOOLKIT_VERBOSE=1 is: toolkit/core/config.py): print every build log in full
        # (Intel's compiler reports its progress and vectorization there; pyopencl would show any
        # non-empty log as a CompilerWarning).
        self.verbose_builds = False

    def once(self, step, run):
        """What `run()` returned the first time `step` was asked for in this session."""
        if step not in self.done:
            self.done[step] = run()
        return self.done[step]


current = None     # the process's Session, made by session()


def session():
    """The Session of this process, made the first time it is asked for."""
    global current
    if current is None:
        current = Session()
    return current


def reset_session():
    """Forget everything: the next call to session() starts a new Session (for tests)."""
    global current
    current = None
