"""The host's traffic with the device, counted in one place: every kernel launch, every copy and
fill, and every time the host waits for the queue, while a `Traffic` records (`with Traffic() as
traffic:`). It is the host meter's counter (toolkit/measure/host_meter.py, `bench --host`).

It wraps pyopencl's own entry points for the time it records, and restores them after:
`enqueue_nd_range_kernel` (program.launch's launches), `enqueue_copy` (reads, writes and copies
on the device), `enqueue_fill_buffer`, `Event.wait` and `CommandQueue.finish`. The toolkit calls
them all as `cl.<name>`, so no technique has a line of measuring code, and a render that is not
measured pays nothing. Only the thread that started the recording is counted (the one that drives
the queue: a demo's other tabs are not this render's).

Why count waits: a GPU finishes a kernel in tens of microseconds. A *blocking* read (or write: on
an in-order queue it waits for every command before it too), a `finish`, or a `wait` on the last
command queued, empties the device's queue; until the host launches again, the device has nothing
to do. The host's CPU time from such a drain to its next launch is `serial_seconds`: host time
that no kernel can hide (toolkit/measure/gpu_model.py adds it to the kernels' time). An
asynchronous read waited for later, behind other queued work, is no drain.

Why time the waits: the thread's CPU time inside a call that waits for the device is not host
work. Where a wait sleeps (PoCL) it is next to nothing; where the waiting thread runs the kernels
itself (Intel's CPU runtime: the waiter joins its worker pool), it is the kernels' own time, 0.56 s
of a 0.73 s pt_compact_regen render measured on an AMD EPYC. `wait_cpu_seconds` keeps it apart,
so that the host meter counts what the host does, on either runtime.
"""
import threading
import time

import numpy as np
import pyopencl as cl

FIGURES = ("launches", "fills", "reads", "blocking_reads", "read_bytes", "writes", "blocking_writes",
           "write_bytes", "device_copies", "drains", "serial_seconds", "cpu_seconds", "wait_cpu_seconds")


class Traffic:
    """What the host asked of the device while recording, on the recording thread:
    - `launches`: kernels enqueued; `fills`: enqueue_fill_buffer calls;
    - `reads`, `read_bytes`, `blocking_reads`: device -> host copies, their bytes, how many blocked;
    - `writes`, `write_bytes`, `blocking_writes`: host -> device copies;
    - `device_copies`: buffer -> buffer copies (no host memory);
    - `drains`: times the host emptied the device's queue (blocking transfers, finish, a wait on the
      last command queued); `serial_seconds`: the host's CPU time from each drain (and from the
      start) to its next launch, when the device had nothing to run;
    - `cpu_seconds`: the recording thread's CPU time while recording (time.thread_time);
      `wait_cpu_seconds`: the part of it inside calls that wait for the device (blocking copies,
      Event.wait, finish; module docstring)."""

    _active = None    # the Traffic recording now (one at a time: the wrappers are process-wide)

    def __init__(self):
        for name in FIGURES:
            setattr(self, name, 0)
        self.serial_seconds = self.cpu_seconds = self.wait_cpu_seconds = 0.0
        self._thread = None
        self._queued = 0          # commands enqueued so far (a sequence number)
        self._event_number = {}   # event handle -> its command's sequence number
        self._drained_at = None   # thread time of the last drain, until the next launch
        self._saved = []

    def figures(self):
        return {name: getattr(self, name) for name in FIGURES}

    # -- recording --------------------------------------------------------------------------

    def __enter__(self):
        if Traffic._active is not None:
            raise RuntimeError("a Traffic recording is already active")
        Traffic._active = self
        self._thread = threading.get_ident()
        self._start = self._drained_at = time.thread_time()   # the device idles until the first launch
        self._install()
        return self

    def __exit__(self, *exc):
        self._restore()
        Traffic._active = None
        now = time.thread_time()
        self._end_serial(now)
        self.cpu_seconds = now - self._start
        return False

    def _install(self):
        real_launch, real_copy, real_fill = cl.enqueue_nd_range_kernel, cl.enqueue_copy, cl.enqueue_fill_buffer
        real_wait, real_finish = cl.Event.wait, cl.CommandQueue.finish

        def enqueue_nd_range_kernel(queue, kernel, *args, **kwargs):
            ours = self._ours()
            if ours:
                self._end_serial(time.thread_time())
                self.launches += 1
            return self._queued_event(real_launch(queue, kernel, *args, **kwargs), ours)

        def enqueue_copy(queue, dest, src, **kwargs):
            ours = self._ours()
            blocking = ours and kwargs.get("is_blocking", True) and not (_on_device(dest) and _on_device(src))
            if ours:
                self._note_copy(dest, src, kwargs)
            start = time.thread_time() if blocking else None
            event = self._queued_event(real_copy(queue, dest, src, **kwargs), ours)
            if blocking:
                self._waited(start)
                self._drained()
            return event

        def enqueue_fill_buffer(queue, *args, **kwargs):
            ours = self._ours()
            if ours:
                self.fills += 1
            return self._queued_event(real_fill(queue, *args, **kwargs), ours)

        def wait(event):
            start = time.thread_time()
            result = real_wait(event)
            if self._ours():
                self._waited(start)
                # Waiting for the last command queued empties the queue; for an older one, the
                # device still has the commands queued after it to run.
                if self._event_number.get(event.int_ptr) == self._queued:
                    self._drained()
            return result

        def finish(queue):
            start = time.thread_time()
            result = real_finish(queue)
            if self._ours():
                self._waited(start)
                self._drained()
            return result

        for owner, name, wrapper in ((cl, "enqueue_nd_range_kernel", enqueue_nd_range_kernel),
                                     (cl, "enqueue_copy", enqueue_copy), (cl, "enqueue_fill_buffer", enqueue_fill_buffer),
                                     (cl.Event, "wait", wait), (cl.CommandQueue, "finish", finish)):
            self._saved.append((owner, name, getattr(owner, name)))
            setattr(owner, name, wrapper)

    def _restore(self):
        for owner, name, real in reversed(self._saved):
            setattr(owner, name, real)
        self._saved = []

    # -- what each call counts ---------------------------------------------------------------

    def _ours(self):
        return threading.get_ident() == self._thread

    def _queued_event(self, event, ours):
        if ours:
            self._queued += 1
            if event is not None:
                self._event_number[event.int_ptr] = self._queued
        return event

    def _note_copy(self, dest, src, kwargs):
        blocking = kwargs.get("is_blocking", True)
        if _on_device(src) and _on_device(dest):
            self.device_copies += 1
        elif _on_device(src):
            self.reads += 1
            self.blocking_reads += bool(blocking)
            self.read_bytes += _host_bytes(dest, kwargs)
        else:
            self.writes += 1
            self.blocking_writes += bool(blocking)
            self.write_bytes += _host_bytes(src, kwargs)

    def _waited(self, start):
        self.wait_cpu_seconds += time.thread_time() - start

    def _drained(self):
        self.drains += 1
        if self._drained_at is None:
            self._drained_at = time.thread_time()

    def _end_serial(self, now):
        if self._drained_at is not None:
            self.serial_seconds += now - self._drained_at
            self._drained_at = None


def _on_device(obj):
    return isinstance(obj, cl.MemoryObjectHolder)


def _host_bytes(host, kwargs):
    """The bytes a copy moves to or from host memory `host` (pyopencl's rule: the host array's
    size, or byte_count when given)."""
    return int(kwargs.get("byte_count") or memoryview(np.asarray(host)).nbytes)
