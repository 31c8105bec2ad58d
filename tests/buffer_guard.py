"""A host-side guard against out-of-bounds device writes: every cl.Buffer made while the guard
is installed becomes a sub-buffer of a larger one whose extra words before and after hold a
known pattern (canaries). After the run, `check()` reads the parents back and names every
buffer whose canaries changed. The kernels see buffers of exactly the requested size."""
import numpy as np
import pyopencl as cl

CANARY = np.uint32(0xDEADBEEF)


class BufferGuard:
    # Front padding: a multiple of every device's sub-buffer alignment (CL_DEVICE_MEM_BASE_ADDR_ALIGN,
    # 1024 bits on PoCL, up to 4096 on GPUs). Back padding: several BDPT vertices (80 bytes each).
    FRONT, BACK = 4096, 4096

    def __init__(self, monkeypatch):
        self.real = cl.Buffer
        self.guarded = []      # (parent, requested size, where it was made)
        monkeypatch.setattr(cl, "Buffer", self.make)

    def make(self, context, flags, size=0, hostbuf=None):
        data = None
        if hostbuf is not None:
            data = np.ascontiguousarray(hostbuf).reshape(-1).view(np.uint8)
            size = size or data.nbytes
        if size <= 0:
            return self.real(context, flags, size, hostbuf)
        host = np.full((self.FRONT + size + self.BACK + 3) // 4, CANARY, np.uint32).view(np.uint8)
        if data is not None:
            host[self.FRONT:self.FRONT + size] = data[:size]
        keep = flags & (cl.mem_flags.READ_WRITE | cl.mem_flags.READ_ONLY | cl.mem_flags.WRITE_ONLY)
        parent = self.real(context, keep | cl.mem_flags.COPY_HOST_PTR, hostbuf=host)
        self.guarded.append((parent, size, host.nbytes))
        return parent.get_sub_region(self.FRONT, size)

    def check(self, queue):
        """Descriptions of the buffers whose canaries changed (empty: none)."""
        queue.finish()
        damaged = []
        for parent, size, total in self.guarded:
            host = np.empty(total, np.uint8)
            cl.enqueue_copy(queue, host, parent)
            front = host[:self.FRONT].view(np.uint32)
            back = host[self.FRONT + size:]
            back = back[:len(back) // 4 * 4].view(np.uint32)
            bad_front, bad_back = int((front != CANARY).sum()), int((back != CANARY).sum())
            if bad_front or bad_back:
                damaged.append(f"buffer of {size} bytes: {bad_front} word(s) before it and "
                               f"{bad_back} after it overwritten")
        return damaged
