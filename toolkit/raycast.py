"""Host side of cl/raycast.cl: closest-hit and any-hit ray casts through the device BVH.

Rays are given in the device's rebased coordinates (world points minus DeviceScene.center, in float64) as float32;
results come back as numpy arrays, prims as the scene's original triangle indices.
"""
import numpy as np
import pyopencl as cl

from . import program


def _pack(vectors, w=None):
    """(N, 3) -> contiguous (N, 4) float32 with .w = w (0 if None)."""
    v = np.asarray(vectors, np.float32)
    packed = np.zeros((len(v), 4), np.float32)
    packed[:, :3] = v[:, :3]
    if w is not None:
        packed[:, 3] = np.broadcast_to(np.asarray(w, np.float32), (len(v),))
    return packed


class DeviceRaycaster:
    """Cast rays through a DeviceScene's BVH with the same traversal the renderers use."""

    def __init__(self, queue, device_scene):
        self.queue = queue
        self.device_scene = device_scene
        self.program = program.build(queue.context, "raycast.cl", device_scene.features())
        self._closest = cl.Kernel(self.program, "raycast_closest")
        self._any = cl.Kernel(self.program, "raycast_any")

    def _buffers(self, origins, dirs, w=None):
        mf = cl.mem_flags
        ctx = self.queue.context
        o = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=_pack(origins))
        d = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=_pack(dirs, w))
        return o, d

    def closest(self, origins, dirs):
        """(t, prim, u, v): closest hit in (0, inf); prim = -1 and t = inf on a miss."""
        n = len(origins)
        if n == 0:
            e = np.zeros(0, np.float32)
            return e, np.zeros(0, np.int32), e, e
        o, d = self._buffers(origins, dirs)
        out = np.empty((n, 4), np.float32)
        prim = np.empty(n, np.int32)
        out_buf = cl.Buffer(self.queue.context, cl.mem_flags.WRITE_ONLY, out.nbytes)
        prim_buf = cl.Buffer(self.queue.context, cl.mem_flags.WRITE_ONLY, prim.nbytes)
        program.launch(self.queue, self._closest, n, *self.device_scene.args(), np.int32(n),
                       o, d, out_buf, prim_buf)
        cl.enqueue_copy(self.queue, out, out_buf)
        cl.enqueue_copy(self.queue, prim, prim_buf)
        self.queue.finish()
        return out[:, 0].copy(), prim, out[:, 1].copy(), out[:, 2].copy()

    def occluded(self, origins, dirs, tmax):
        """Whether anything lies on each segment (0, tmax) (bool array)."""
        n = len(origins)
        if n == 0:
            return np.zeros(0, bool)
        o, d = self._buffers(origins, dirs, tmax)
        blocked = np.empty(n, np.int32)
        buf = cl.Buffer(self.queue.context, cl.mem_flags.WRITE_ONLY, blocked.nbytes)
        program.launch(self.queue, self._any, n, *self.device_scene.args(), np.int32(n), o, d, buf)
        cl.enqueue_copy(self.queue, blocked, buf)
        self.queue.finish()
        return blocked != 0
