"""Prefix sums and a stable LSD radix sort of uint32 keys (with uint32 values) in GLSL compute
shaders: the order stays on the GPU. glsl/scan_*.comp and glsl/sort_*.comp hold the kernels.

One radix pass per 8-bit digit: a per-block histogram (blocks of :data:`BLOCK` keys), one
exclusive scan of all histograms (digit-major, so it yields each (digit, block)'s first slot),
and a stable scatter. The numpy sort (rendering/depth_order.py) is the fallback and the test oracle.
"""

from __future__ import annotations

import moderngl
import numpy as np

from dofview.errors import BackendUnavailable, DofviewError
from dofview.rendering.gl import compute_shader

THREADS = 64  # scatter/histogram workgroup; a multiple of 4 (byte counters four to a word)
ITEMS = 32    # keys per thread; ≤ 63 so that four threads' byte counters never carry
BLOCK = THREADS * ITEMS
SCAN_BLOCK = 1024
MAX_GROUPS = 65535
GL_COMPUTE = 430


def groups(n: int) -> tuple[int, int]:
    """A 2D dispatch of ``n`` workgroups (glsl/dispatch.glsl turns it back into one index)."""
    if n <= MAX_GROUPS:
        return max(n, 1), 1
    return MAX_GROUPS, -(-n // MAX_GROUPS)


def require_compute(ctx: moderngl.Context) -> None:
    """Raise :class:`BackendUnavailable` unless this GL runs compute shaders with storage buffers."""
    if ctx.version_code < GL_COMPUTE:
        raise BackendUnavailable(f"compute shaders need OpenGL 4.3; this context is "
                                 f"{ctx.version_code // 100}.{ctx.version_code % 100 // 10}")


def max_buffer_bytes(ctx: moderngl.Context) -> int:
    """The largest storage buffer one shader may bind (GL_MAX_SHADER_STORAGE_BLOCK_SIZE)."""
    return int(ctx.info["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"])


class GpuScan:
    """In-place exclusive prefix sum of a uint32 storage buffer (multi-level, any length)."""

    def __init__(self, ctx: moderngl.Context) -> None:
        require_compute(ctx)
        self.ctx = ctx
        self._block = compute_shader(ctx, "scan_block.comp")
        self._add = compute_shader(ctx, "scan_add.comp")
        self._levels: list[moderngl.Buffer] = []

    def _level(self, i: int, count: int) -> moderngl.Buffer:
        """Scratch for the block totals of level ``i`` (grown, never shrunk)."""
        size = 4 * max(count, 1)
        if i == len(self._levels):
            self._levels.append(self.ctx.buffer(reserve=size))
        elif self._levels[i].size < size:
            self._levels[i].release()
            self._levels[i] = self.ctx.buffer(reserve=size)
        return self._levels[i]

    def run(self, data: moderngl.Buffer, n: int, level: int = 0) -> None:
        """Replace data[0:n] by its exclusive prefix sum (uint32, wrapping at 2³²)."""
        if n <= 0:
            return
        blocks = -(-n // SCAN_BLOCK)
        sums = self._level(level, blocks)
        data.bind_to_storage_buffer(0)
        sums.bind_to_storage_buffer(1)
        self._block["u_n"].value = n
        self._block.run(*groups(blocks))
        self.ctx.memory_barrier()
        if blocks > 1:
            self.run(sums, blocks, level + 1)
            data.bind_to_storage_buffer(0)
            sums.bind_to_storage_buffer(1)
            self._add["u_n"].value = n
            self._add.run(*groups(blocks))
            self.ctx.memory_barrier()

    def release(self) -> None:
        for obj in (*self._levels, self._block, self._add):
            obj.release()


class GpuRadixSort:
    """Stable ascending sort of (uint32 key, uint32 value) pairs held in GPU buffers.

    Scratch buffers (keys and values, as long as the longest sort) are the caller's, so that a
    renderer can share them between its sorts; :meth:`argsort` is the host-side convenience.
    """

    def __init__(self, ctx: moderngl.Context) -> None:
        require_compute(ctx)
        self.ctx = ctx
        defines = {"THREADS": f"{THREADS}u", "ITEMS": f"{ITEMS}u"}
        self._hist = compute_shader(ctx, "sort_histogram.comp", defines)
        self._scatter = compute_shader(ctx, "sort_scatter.comp", defines)
        self.scan = GpuScan(ctx)
        self._offsets: moderngl.Buffer | None = None

    def _offsets_for(self, blocks: int) -> moderngl.Buffer:
        size = 4 * 256 * blocks
        if self._offsets is None or self._offsets.size < size:
            if self._offsets is not None:
                self._offsets.release()
            self._offsets = self.ctx.buffer(reserve=size)
        return self._offsets

    def sort(self, keys: moderngl.Buffer, values: moderngl.Buffer, n: int, bits: int,
             scratch_keys: moderngl.Buffer, scratch_values: moderngl.Buffer) -> tuple[moderngl.Buffer, moderngl.Buffer]:
        """Sort ``n`` pairs by the low ``bits`` bits of the keys (higher bits must be 0 or are
        ignored); ties keep their input order. Returns the (keys, values) buffers now holding the
        result: the inputs after an even number of 8-bit passes, the scratch pair after an odd one.
        """
        if n > 0 and 4 * n > min(keys.size, values.size, scratch_keys.size, scratch_values.size):
            raise DofviewError(f"radix sort of {n} keys needs buffers of {4 * n} bytes")
        src, dst = (keys, values), (scratch_keys, scratch_values)
        if n <= 1:
            return src
        blocks = -(-n // BLOCK)
        offsets = self._offsets_for(blocks)
        for shift in range(0, max(bits, 1), 8):
            src[0].bind_to_storage_buffer(0)
            offsets.bind_to_storage_buffer(1)
            for prog in (self._hist, self._scatter):
                prog["u_n"].value = n
                prog["u_shift"].value = shift
                prog["u_blocks"].value = blocks
            self._hist.run(*groups(blocks))
            self.ctx.memory_barrier()
            self.scan.run(offsets, 256 * blocks)
            for binding, buf in enumerate((*src, *dst, offsets)):
                buf.bind_to_storage_buffer(binding)
            self._scatter.run(*groups(blocks))
            self.ctx.memory_barrier()
            src, dst = dst, src
        return src

    def argsort(self, keys: np.ndarray) -> np.ndarray:
        """(N,) uint32 keys → (N,) uint32 stable ascending order, sorted on the GPU."""
        keys = np.ascontiguousarray(keys, dtype=np.uint32)
        n = keys.size
        if n == 0:
            return np.zeros(0, np.uint32)
        bufs = [self.ctx.buffer(keys), self.ctx.buffer(np.arange(n, dtype=np.uint32)),
                self.ctx.buffer(reserve=4 * n), self.ctx.buffer(reserve=4 * n)]
        try:
            _, values = self.sort(*bufs[:2], n, 32, *bufs[2:])
            return np.frombuffer(values.read(size=4 * n), np.uint32).copy()
        finally:
            for b in bufs:
                b.release()

    @property
    def gpu_bytes(self) -> int:
        """Bytes of scratch now held (histograms and scan levels)."""
        return (self._offsets.size if self._offsets else 0) + sum(b.size for b in self.scan._levels)

    def release(self) -> None:
        for obj in (self._hist, self._scatter, self._offsets):
            if obj is not None:
                obj.release()
        self.scan.release()
