"""Host side of cl/raycast.cl: closest-hit and any-hit ray casts through the device BVH.

Rays are given in the device's rebased coordinates (world points minus DeviceScene.center, in float64) as float32;
results come back as numpy arrays, prims as the scene's original triangle indices.
"""
import numpy as np
import pyopencl as cl

from toolkit.opencl import program


def _rays(vectors):
    """(N, 3) float32, C-contiguous: what the kernels read (no copy when it already is)."""
    v = np.ascontiguousarray(vectors, np.float32)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"expected an (N, 3) array of rays, got shape {v.shape}")
    return v


class DeviceRaycaster:
    """Cast rays through a DeviceScene's BVH with the same traversal the renderers use."""

    def __init__(self, queue, device_scene):
        self.queue = queue
        self.device_scene = device_scene
        self.program = program.build(queue, "raycast.cl", device_scene.features())
        self._closest = cl.Kernel(self.program, "raycast_closest")
        self._any = cl.Kernel(self.program, "raycast_any")

    def _input(self, array):
        """A read-only buffer over a host array, used in place where the device can (a CPU
        device reads the host's memory: no copy), copied where it cannot."""
        return cl.Buffer(self.queue.context, cl.mem_flags.READ_ONLY | cl.mem_flags.USE_HOST_PTR, hostbuf=array)

    def _output(self, n, dtype):
        return np.empty(n, dtype), cl.Buffer(self.queue.context, cl.mem_flags.WRITE_ONLY, n * np.dtype(dtype).itemsize)

    def closest(self, origins, dirs):
        """(t, prim, u, v): closest hit in (0, inf); prim = -1 and t = inf on a miss."""
        origins, dirs = _rays(origins), _rays(dirs)
        n = len(origins)
        if n == 0:
            e = np.zeros(0, np.float32)
            return e, np.zeros(0, np.int32), e, e
        if n >= 1 << 29:
            raise ValueError(f"{n} rays in one call; at most {(1 << 29) - 1} (the kernel indexes 4 n words with an int)")
        out, buf = self._output(4 * n, np.float32)
        program.launch(self.queue, self._closest, n, *self.device_scene.args(), np.int32(n),
                       self._input(origins), self._input(dirs), buf)
        cl.enqueue_copy(self.queue, out, buf)
        self.queue.finish()    # the inputs are the caller's arrays: done with them before returning
        t, u, v, prim = out.reshape(4, n)
        return t, prim.view(np.int32), u, v

    def occluded(self, origins, dirs, tmax):
        """Whether anything lies on each segment (0, tmax) (bool array)."""
        origins, dirs = _rays(origins), _rays(dirs)
        n = len(origins)
        if n == 0:
            return np.zeros(0, bool)
        tmax = np.ascontiguousarray(np.broadcast_to(np.asarray(tmax, np.float32), (n,)))
        blocked, buf = self._output(n, np.int32)
        program.launch(self.queue, self._any, n, *self.device_scene.args(), np.int32(n),
                       self._input(origins), self._input(dirs), self._input(tmax), buf)
        cl.enqueue_copy(self.queue, blocked, buf)
        self.queue.finish()
        return blocked != 0
