"""Choosing the OpenCL device: the first usable GPU, else the best usable CPU implementation.

"Usable" is measured, not assumed: each device builds and runs a small probe kernel
(`cl/probe.cl`, which uses what the toolkit's kernels use) once; the verdict is cached on disk
per device, driver version and CPU (toolkit/opencl/probe_cache.py). A device whose compiler
fails (PoCL 3.0's LLVM 14 on an AMD Zen 5, for one) is skipped, with the compiler's first error
line as the reason.

Ranking among usable devices (`RANKING`): a GPU first; then PoCL (the newest version first: a
distribution's PoCL, whose newer LLVM knows newer CPUs, before pip's 3.0); then Intel's CPU
runtime; then any other implementation. Intel's runtime (with SIMD lanes off, see
toolkit/opencl/lanes.py) is faster on our kernels than PoCL on a 2-core AMD EPYC (1.4x for pt_naive
and bdpt_parallel_connect), but PoCL comes first: it is open source, it is what the project's
figures and tests are measured on, and Intel's runtime is the fallback for CPUs that PoCL 3.0
cannot compile for. Pick Intel's with `--device intel` for speed. Oclgrind is a simulator for
finding memory errors, a thousand times slower: it is only used when asked for by name.

`choose` says why it picked what it picked, naming the device and the cause (a GPU that passed
the probe; else no GPU, or the GPUs that failed the probe and why), and `python -m toolkit
devices` prints that. A GPU on a learner's laptop (Apple's, or a driver's on Windows) needs no
set-up: toolkit/opencl/runtimes.py registers only what pip installed, where it installed it.

`--device` / `PYOPENCL_CTX` (`P:D` indices or a part of the name) override the automatic
choice; `TOOLKIT_HIDE_PLATFORMS` (comma-separated parts of platform names) makes platforms
count as unusable, e.g. to run on Intel's runtime where PoCL also works.
`python -m toolkit devices` prints every device, usable or why not, and the ranking.
"""
import platform as host_platform
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyopencl as cl

from toolkit.core.config import config
from toolkit.opencl import lanes, runtimes
from toolkit.opencl.builds import Builds, Queue
from toolkit.opencl.device_model import is_gpu
from toolkit.opencl.install_advice import fixes_when_nothing_builds, how_to_get_opencl
from toolkit.opencl.probe_cache import read_verdict, verdict_file, write_verdict
from toolkit.opencl.program import LOCAL_SIZE, KernelBuildError, WorkGroupTooLarge, build, expand_includes, kernel, launch
from toolkit.opencl.runtimes import intel_cpu_library
from toolkit.opencl.session import session


class NoOpenCLError(RuntimeError):
    pass


RANKING = ("GPU", "PoCL (newest first)", "Intel CPU runtime", "other", "Oclgrind (only by name)")
# What comes first at each rank, for the reason of a choice ("..., so PoCL comes next").
RANK_NAMES = ("a GPU", "PoCL", "Intel's CPU runtime", "an implementation of another vendor", "Oclgrind")


@dataclass
class Candidate:
    platform_index: int
    device_index: int
    platform: object
    device: object
    usable: bool = True
    reason: str = ""          # why not usable; "" when usable

    @property
    def selector(self):
        return f"{self.platform_index}:{self.device_index}"

    @property
    def is_gpu(self):
        return is_gpu(self.device)

    @property
    def implementation(self):
        """The OpenCL implementation and its version, e.g. "PoCL 3.0-rc2"."""
        name = self.platform.name.strip()
        if "Portable Computing Language" in name:
            return f"PoCL {self.device.driver_version.strip()}"
        return f"{name} {self.device.driver_version.strip()}"

    @property
    def compiler(self):
        """The kernel compiler and its version, as far as the implementation tells."""
        llvm = re.search(r"LLVM\s+([\d.]+)", self.platform.version)
        if llvm:
            return f"LLVM {llvm.group(1)}"
        if "Intel" in self.platform.name:
            return f"Intel OpenCL CPU compiler {self.device.driver_version.strip()}"
        return f"driver {self.device.driver_version.strip()}"

    @property
    def rank(self):
        """Smaller is better; see RANKING."""
        name = self.platform.name
        if "Oclgrind" in name:
            return (4, 0)
        if self.is_gpu:
            return (0, 0)
        if "Portable Computing Language" in name:
            version = [int(x) for x in re.findall(r"\d+", self.device.driver_version)[:2]]
            return (1, tuple(-v for v in version))
        if "Intel" in name:
            return (2, 0)
        return (3, 0)


def list_devices():
    """All (platform_index, device_index, platform, device) tuples; [] if there is no platform."""
    runtimes.prepare()   # pip's runtimes registered before the loader's first look (once per process)
    try:
        platforms = cl.get_platforms()
    except cl.Error:
        return []
    found = []
    for pi, platform in enumerate(platforms):
        try:
            devices = platform.get_devices()
        except cl.Error:
            continue
        for di, device in enumerate(devices):
            found.append((pi, di, platform, device))
    return found


def _hidden(platform):
    return any(part in platform.name.lower() for part in config().hide_platforms)


def candidates(probe_all=True):
    """Every device as a Candidate, probed (usable or the reason), best first."""
    found = [Candidate(pi, di, p, d) for pi, di, p, d in list_devices()]
    for c in found:
        if _hidden(c.platform):
            c.usable, c.reason = False, "hidden by TOOLKIT_HIDE_PLATFORMS"
        elif probe_all:
            c.usable, c.reason = probe(c.device)
    return sorted(found, key=lambda c: (not c.usable, c.rank, c.platform_index, c.device_index))


# ---- the probe -------------------------------------------------------------------------------

PROBE_ITEMS = 256


def _probe_identity(device):
    """What a probe's verdict depends on besides the CPU (probe_cache.py adds that)."""
    return "\0".join([device.platform.name, device.platform.version, device.name, device.driver_version,
                      device.version, expand_includes("probe.cl"), cl.VERSION_TEXT])


def probe(device):
    """(usable, reason) for a device: build and run cl/probe.cl and check what it wrote.
    Kept for the process (the Session's probe_verdicts, toolkit/opencl/session.py) and on disk per
    device, driver version, probe source and CPU (toolkit/opencl/probe_cache.py: what is kept, and
    what is not)."""
    file = verdict_file(_probe_identity(device))
    verdicts, notes = session().probe_verdicts, session().probe_notes
    if file in verdicts:
        return verdicts[file]
    cached = read_verdict(file)
    if cached is not None:
        verdicts[file] = cached
        notes[file] = f"cached verdict in {file} (delete it to probe again)"
        return cached
    usable, reason, lasting = _run_probe(device)
    verdicts[file] = usable, reason
    if lasting:
        problem = write_verdict(file, usable, reason, device.name.strip())
        notes[file] = f"probed now; verdict {problem or f'kept in {file}'}"
    else:
        notes[file] = "probed now; not kept (an OpenCL error says nothing lasting about the device)"
    return verdicts[file]


def probe_note(device):
    """Where the device's probe verdict came from, or "" if it was not probed in this process."""
    return session().probe_notes.get(verdict_file(_probe_identity(device)), "")


def _run_probe(device):
    """(usable, reason, lasting): `lasting` when the verdict holds for later runs (see probe_cache.py)."""
    try:
        queue = queue_for_device(device)
        program = build(queue, "probe.cl")
        lengths = cl.Buffer(queue.context, cl.mem_flags.WRITE_ONLY, PROBE_ITEMS * 4)
        groups = PROBE_ITEMS // LOCAL_SIZE
        sums = cl.Buffer(queue.context, cl.mem_flags.WRITE_ONLY, groups * 4)
        counter = np.zeros(1, np.int32)
        counter_buffer = cl.Buffer(queue.context, cl.mem_flags.READ_WRITE | cl.mem_flags.COPY_HOST_PTR, hostbuf=counter)
        launch(queue, kernel(program, "probe"), PROBE_ITEMS, lengths, sums, counter_buffer)
        host_lengths, host_sums = np.empty(PROBE_ITEMS, np.float32), np.empty(groups, np.int32)
        cl.enqueue_copy(queue, host_lengths, lengths)
        cl.enqueue_copy(queue, host_sums, sums)
        cl.enqueue_copy(queue, counter, counter_buffer)
        queue.finish()
    except KernelBuildError as error:   # the compiler's verdict lasts; a build it could not run does not
        return False, first_error_line(str(error)), "BUILD_PROGRAM_FAILURE" in str(error)
    except WorkGroupTooLarge as error:  # Apple's CPU device limits some kernels' work-groups
        return False, str(error), True
    except cl.Error as error:
        return False, f"OpenCL error while probing: {str(error).splitlines()[0]}", False
    expected_sums = np.arange(PROBE_ITEMS).reshape(groups, LOCAL_SIZE).sum(axis=1)
    if not (np.all(np.abs(host_lengths - 1) < 1e-5) and np.array_equal(host_sums, expected_sums)
            and counter[0] == PROBE_ITEMS):
        return False, "the probe kernel ran but computed wrong numbers", True
    return True, "", True


def first_error_line(log):
    """The compiler's first error line of a build report (what `devices` shows as the reason)."""
    lines = [line.strip() for line in log.split("Full compiler log:")[-1].splitlines() if line.strip()]
    for line in lines:
        if re.search(r"\berror\b", line, re.IGNORECASE) and "clBuildProgram failed" not in line:
            return line
    return lines[0] if lines else "the build failed without a log"


# ---- picking ---------------------------------------------------------------------------------

def _parse_selector(selector, found):
    """A selector is "P:D" (indices, like PYOPENCL_CTX), "P" or a case-insensitive substring
    of the device or platform name ("gpu" and "cpu" match the device type); among several
    matches the best-ranked usable one wins."""
    selector = str(selector).strip()
    parts = selector.split(":")
    if all(p.isdigit() for p in parts if p) and parts[0]:
        pi = int(parts[0])
        di = int(parts[1]) if len(parts) > 1 and parts[1] else 0
        for c in found:
            if c.platform_index == pi and c.device_index == di:
                return c
        raise NoOpenCLError(f"no OpenCL device {pi}:{di}; run `python -m toolkit devices`")
    needle = selector.lower()
    for c in found:  # `found` is sorted best first
        kind = cl.device_type.to_string(c.device.type).lower()
        if needle in c.device.name.lower() or needle in c.platform.name.lower() or needle in kind:
            return c
    raise NoOpenCLError(f"no OpenCL device matches {selector!r}; run `python -m toolkit devices`")


def pick_device(selector=None):
    """The (platform, device) the toolkit uses: selector, else PYOPENCL_CTX, else the best usable."""
    found = candidates()
    if not found:
        raise NoOpenCLError(how_to_get_opencl())
    selector = selector or config().pyopencl_ctx
    if selector:
        chosen = _parse_selector(selector, found)
        if not chosen.usable:
            raise NoOpenCLError(f"OpenCL device {chosen.selector} ({describe(chosen.device)}) cannot "
                                f"build the toolkit's kernels: {chosen.reason}")
        return chosen.platform, chosen.device
    chosen, _ = choose(found)
    return chosen.platform, chosen.device


def choose(found):
    """(the Candidate picked automatically from `found`, why): the best usable one by RANKING,
    and a sentence that names it and the cause. NoOpenCLError when none can build."""
    if not found:
        raise NoOpenCLError(how_to_get_opencl())
    automatic = [c for c in found if c.usable and c.rank[0] < 4]
    if not automatic:
        raise NoOpenCLError(explain_no_usable_device(found))
    chosen = automatic[0]
    name = f"{chosen.device.name.strip()} ({chosen.implementation})"
    passed_over = [f"{c.device.name.strip()} ({c.implementation}) {_why_not(c)}" for c in found
                   if not c.usable and c.rank <= chosen.rank]
    if chosen.is_gpu:
        why = f"{name} is a GPU and passed the probe: a GPU comes first"
    else:
        gpus = [c for c in found if c.is_gpu]
        why = (f"{name}: no GPU passed the probe" if gpus else f"{name}: there is no GPU") + \
            f", and {RANK_NAMES[chosen.rank[0]]} comes next in the ranking"
    return chosen, why + "".join(f"; {line}" for line in passed_over)


def _why_not(c):
    """How an unusable device fell out: "failed the probe: <the compiler's error>", or hidden."""
    return f"is {c.reason}" if c.reason.startswith("hidden") else f"failed the probe: {c.reason}"


def explain_no_usable_device(found):
    """The error when no device can build: the cause, and the fixes that apply here."""
    lines = ["No OpenCL device can build the toolkit's kernels:"]
    for c in found:
        note = probe_note(c.device) if not c.usable else ""
        lines.append(f"  {c.selector} {describe(c.device)}, {c.implementation} ({c.compiler}): "
                     f"{c.reason or 'a simulator, only used when selected with --device'}"
                     + (f" ({note})" if note.startswith("cached") else ""))
    unknown_cpu = [c for c in found if "unknown target CPU" in c.reason]
    if unknown_cpu:
        c = unknown_cpu[0]
        lines.append(f"Cause: {c.implementation}'s {c.compiler} does not know this CPU "
                     f"({_cpu_name()}), so it cannot compile for it.")
    lines.append("Fixes:")
    lines += [f"  - {fix}" for fix in fixes_when_nothing_builds(intel_cpu_library() is not None)]
    if config().hide_platforms:
        lines.append(f"  - TOOLKIT_HIDE_PLATFORMS={','.join(config().hide_platforms)} hides some platforms; unset it")
    return "\n".join(lines)


def _cpu_name():
    try:
        info = Path("/proc/cpuinfo").read_text()
        name = re.search(r"model name\s*:\s*(.+)", info)
        family = re.search(r"cpu family\s*:\s*(\d+)", info)
        return f"{name.group(1).strip()}, CPU family {family.group(1)}" if name and family else host_platform.processor()
    except OSError:
        return host_platform.processor() or "unknown CPU"


def _context_and_queue(device, setting=None):
    """The process's one (context, queue) of `device` and lanes setting, kept in the Session's
    queues: a second context would build every program again."""
    # One context per SIMD-lanes setting (toolkit/opencl/lanes.py): its Builds follow it. The
    # queue keeps its Context object alive (builds.Queue: Intel's runtime needs that).
    queues = session().queues
    if (device, setting) not in queues:
        context = cl.Context([device])
        queues[(device, setting)] = context, Queue(context, Builds(setting))
    return queues[(device, setting)]


def queue_for_device(device):
    """The shared queue (builds.Queue) of `device`, with its default lanes setting."""
    return _context_and_queue(device, lanes.setting_for(device))[1]


def get_queue(selector=None, lanes_setting=None):
    """One shared context and in-order queue per device and lanes setting: a builds.Queue, which
    carries the context's Builds (what is built there, kept for the process). `lanes_setting`: "on", "off" or None (TOOLKIT_LANES, else the device's default)."""
    _, device = pick_device(selector or config().pyopencl_ctx)
    return _context_and_queue(device, lanes.setting_for(device, lanes_setting))[1]


def describe(device):
    return f"{device.name.strip()} ({device.platform.name.strip()}, {cl.device_type.to_string(device.type)})"


def describe_implementation(device):
    """"PoCL 3.0-rc2, LLVM 14.0.6" for reports (pytest header, bench)."""
    c = Candidate(0, 0, device.platform, device)
    return f"{c.implementation}, {c.compiler}"


def has_gpu():
    """Whether this machine has a GPU (device_model.is_gpu: Oclgrind's simulator, which reports
    every device type, is not one)."""
    return any(is_gpu(device) for _, _, _, device in list_devices())
