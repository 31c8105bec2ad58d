"""How long each kernel ran, from OpenCL's profiling events: the time of each phase of a technique.

A measuring hook that stays out of the technique's way: every launch goes through
program.launch, which hands its event to `note`; a `KernelTimes` recording on that queue keeps
it. The technique's host loop has no timing code, and a render that records nothing pays nothing.

Profiling needs a queue made with PROFILING_ENABLE: `profiling_queue(queue)` is one on the same
context (so the builds, the scene's buffers and the lanes setting are shared: builds.py). Its events say
when the device started and ended each launch (CL_PROFILING_COMMAND_START / _END, in ns of the
device's clock); on an in-order queue launches never overlap, so their times add up to at most
the wall time of the render that made them.
"""
import time

import pyopencl as cl

from toolkit.opencl.builds import Queue


def profiling_queue(queue):
    """An in-order queue with profiling on the context of `queue` (the same one each time: its
    Builds keeps it), sharing that context's Builds."""
    if queue.properties & cl.command_queue_properties.PROFILING_ENABLE:
        return queue
    builds = queue.builds
    if builds.profiling is None:
        builds.profiling = Queue(queue.context, builds, properties=cl.command_queue_properties.PROFILING_ENABLE)
    return builds.profiling


def note(queue, kernel_name, event):
    """program.launch's hook: keep `event` if a recording is active on `queue`."""
    if queue.recording is not None:
        queue.recording.events.append((kernel_name, event))


class KernelTimes:
    """The launches on one profiling queue while recording (`with KernelTimes(queue) as times:`),
    then `times.per_kernel()`: {kernel: (launches, seconds on the device)}, in order of first launch."""

    def __init__(self, queue):
        if not queue.properties & cl.command_queue_properties.PROFILING_ENABLE:
            raise ValueError("KernelTimes needs a queue with profiling (kernel_times.profiling_queue)")
        self.queue = queue
        self.events = []     # (kernel name, event) per launch
        self._per_kernel = None
        self.reading_seconds = 0.0   # the thread's CPU time spent reading the events (per_kernel): the measuring's own cost

    def __enter__(self):
        if self.queue.recording is not None:
            raise RuntimeError("a KernelTimes recording is already active on this queue")
        self.queue.recording = self
        return self

    def __exit__(self, *exc):
        self.queue.recording = None
        self.queue.finish()   # every event has its end time
        return False

    def per_kernel(self):
        """{kernel: (launches, seconds)} and, once read, the events are let go."""
        if self._per_kernel is None:
            reading = time.thread_time()
            out, first, last = {}, None, None
            for name, event in self.events:
                start, end = event.profile.start, event.profile.end
                launches, seconds = out.get(name, (0, 0.0))
                out[name] = (launches + 1, seconds + (end - start) * 1e-9)
                first = start if first is None else min(first, start)
                last = end if last is None else max(last, end)
            # from the first launch's start to the last one's end, device clock: the kernels' sum fits in it
            self.span_seconds = (last - first) * 1e-9 if first is not None else 0.0
            self._per_kernel, self.events = out, []
            self.reading_seconds = time.thread_time() - reading
        return dict(self._per_kernel)
