"""A NaN planted in the first record of every connect phase, on the device, before a sink adds
it: the BDPT image sink's test and mlt's proposal sink's test both plant it this way."""
import numpy as np
import pyopencl as cl


def plant_nan_in_every_connect_phase(monkeypatch, sink_class):
    """Patch `sink_class.add` to overwrite the first record of each connect phase that has any
    with (NaN, 1, 1, 1) on pixel 0; returns the list that gets one entry per planted NaN."""
    planted, add = [], sink_class.add

    def add_with_a_nan(sink, connections):
        if connections.count:
            queue = connections.queue
            cl.enqueue_copy(queue, connections.value_buffer, np.float32([np.nan, 1.0, 1.0, 1.0]))
            cl.enqueue_copy(queue, connections.pixel_buffer, np.int32([0]))
            planted.append(1)
        add(sink, connections)
    monkeypatch.setattr(sink_class, "add", add_with_a_nan)
    return planted
