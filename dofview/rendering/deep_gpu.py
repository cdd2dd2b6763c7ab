"""Deep images on the GPU: what both backends' ``_deep`` share.

A backend makes each pixel's splats reachable front to back (the compute backend: its binned tile
lists; the quad backend: an A-buffer of its fragments, sorted) and walks them with a compute
program that includes glsl/deep_walk.glsl. :class:`DeepWalk` holds that include's buffers (the
per-pixel state between passes, each pixel's sample count or first slot, the samples) and runs
the image band by band: in each band a counting walk, the samples' slots (a prefix sum of the
counts read back, which the deep image needs anyway), then an emitting walk, and the samples
read back. Bands keep every buffer within :data:`BAND_ITEMS` items and the GL's storage-buffer limit.
"""

from __future__ import annotations

from collections.abc import Callable

import moderngl
import numpy as np

from dofview.deep import DeepSettings
from dofview.errors import DofviewError

BAND_ITEMS = 1 << 23
"""Most fragments (quad backend) or samples one band holds on the GPU (8M: 128 MiB of sample
colours, the largest storage buffer llvmpipe binds)."""
STATE_BYTES = 48  # glsl/deep_walk.glsl: DeepState
LLVMPIPE_WALK = 8000
"""Splats or fragments one walk pass takes per pixel on llvmpipe, which ends an invocation's loops
after 65535 iterations in all and counts several for a loop body with branches (the walk's merge
rule): tests/test_deep.py walks 70 000 fragments of one pixel."""


def band_items(ctx: moderngl.Context) -> int:
    """Fragments or samples a band may hold here: :data:`BAND_ITEMS`, within one storage buffer of
    vec4 sample colours."""
    return min(BAND_ITEMS, int(ctx.info["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"]) // 16)


def split_rows(per_row: np.ndarray, budget: int, what: str, width: int = 0,
               max_pixels: int = 0) -> list[tuple[int, int]]:
    """Consecutive row ranges (r0, r1), ends exclusive, covering ``per_row`` (items in each image
    row), each holding at most ``budget`` items and, when given, ``max_pixels`` pixels of rows
    ``width`` wide (a band always takes at least one row).

    Raises:
        DofviewError: one row holds more than ``budget`` ``what``.
    """
    per_row = np.asarray(per_row, np.int64)
    if per_row.size and per_row.max() > budget:
        raise DofviewError(f"deep output: one image row holds {int(per_row.max())} {what}, more than the "
                           f"{budget} a GPU band holds; render a narrower image")
    rows = max(1, max_pixels // width) if width and max_pixels else len(per_row)
    bands, start, total = [], 0, 0
    for r, n in enumerate(per_row):
        if (total + n > budget or r - start >= rows) and r > start:
            bands.append((start, r))
            start, total = r, 0
        total += int(n)
    bands.append((start, len(per_row)))
    return bands


WalkFn = Callable[[int, int, bool], None]
"""A backend's walk of image rows [r0, r1) (from the top), counting (False) or emitting (True),
every pass of it run through :meth:`DeepWalk.set_pass`."""


class DeepWalk:
    """The buffers of glsl/deep_walk.glsl (bindings 8–11) and the band-by-band run of a deep image.

    Args:
        ctx: the renderer's GL context.
    """

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self._limit = int(ctx.info["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"])
        self._buffers: dict[str, moderngl.Buffer] = {}

    def _buffer(self, name: str, size: int) -> moderngl.Buffer:
        """Storage buffer ``name`` of at least ``size`` bytes (grown by half again within the
        storage-buffer limit, never shrunk)."""
        buf = self._buffers.get(name)
        if buf is None or buf.size < size:
            if buf is not None:
                buf.release()
            buf = self._buffers[name] = self.ctx.buffer(reserve=max(min(size + size // 2, self._limit), size, 16))
        return buf

    @property
    def gpu_bytes(self) -> int:
        return sum(b.size for b in self._buffers.values())

    def count_bands(self, per_row: np.ndarray, width: int, what: str) -> list[tuple[int, int]]:
        """Row ranges to count in (:func:`split_rows`): at most :func:`band_items` of ``per_row``
        and as many pixels as one storage buffer keeps walk states for."""
        return split_rows(per_row, band_items(self.ctx), what, width, self._limit // STATE_BYTES)

    def set_pass(self, program: moderngl.ComputeShader, resume: bool, last: bool) -> None:
        """Bind the walk's buffers to ``program`` and say whether this pass continues an earlier
        one's state and whether it ends the pixels' lists."""
        for binding, name in enumerate(("state", "pixel", "colour", "depth"), start=8):
            self._buffers[name].bind_to_storage_buffer(binding)
        program["u_resume"].value = resume
        program["u_last"].value = last

    def run(self, program: moderngl.ComputeShader, width: int, height: int, deep: DeepSettings, encoded: bool,
            walk: WalkFn, count_bands: list[tuple[int, int]],
            prepare: Callable[[int, int], None] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The deep image of the ``width`` × ``height`` frame as (counts (H, W) int64, colours (S, 4)
        float32, depths (S, 2) float32), pixels row by row from the top, each front to back.

        ``program``: the backend's walk (its uniforms u_reach, u_cap, u_encoded and u_emit are set
        here); ``count_bands``: row ranges the walk can count on its own (after ``prepare(r0, r1)``,
        the quad backend's A-buffer of that band); within each, the samples are emitted in bands
        of at most :func:`band_items`, which ``walk`` must accept within a count band.
        """
        program["u_reach"].value = 1.0 + deep.tolerance
        program["u_cap"].value = deep.cap
        program["u_encoded"].value = encoded
        budget = band_items(self.ctx)
        counts = np.zeros((height, width), np.int64)
        colours, depths = [], []
        for r0, r1 in count_bands:
            if prepare is not None:
                prepare(r0, r1)
            self._size((r1 - r0) * width, 0)
            program["u_emit"].value = False
            walk(r0, r1, False)
            band = np.frombuffer(self._buffers["pixel"].read(size=4 * (r1 - r0) * width), np.uint32)
            counts[r0:r1] = band.reshape(r1 - r0, width)
            for e0, e1 in split_rows(counts[r0:r1].sum(axis=1), budget, "samples"):
                e0, e1 = e0 + r0, e1 + r0
                sub = counts[e0:e1].ravel()
                total = int(sub.sum())
                if not total:
                    continue
                self._size(sub.size, total)
                first = np.concatenate([[0], np.cumsum(sub[:-1])]).astype(np.uint32)
                self._buffers["pixel"].write(first.tobytes())
                program["u_emit"].value = True
                walk(e0, e1, True)
                colours.append(np.frombuffer(self._buffers["colour"].read(size=16 * total), np.float32).reshape(-1, 4))
                depths.append(np.frombuffer(self._buffers["depth"].read(size=8 * total), np.float32).reshape(-1, 2))
        if not colours:
            return counts, np.zeros((0, 4), np.float32), np.zeros((0, 2), np.float32)
        return counts, np.concatenate(colours), np.concatenate(depths)

    def _size(self, pixels: int, samples: int) -> None:
        """The walk's buffers for a band of ``pixels`` pixels and ``samples`` samples."""
        self._buffer("state", STATE_BYTES * max(pixels, 1))
        self._buffer("pixel", 4 * max(pixels, 1))
        self._buffer("colour", 16 * max(samples, 1))
        self._buffer("depth", 8 * max(samples, 1))

    def release(self) -> None:
        for b in self._buffers.values():
            b.release()
        self._buffers.clear()


def walk_take(ctx: moderngl.Context) -> int | None:
    """Items a walk pass takes per pixel on this GL (None: no limit)."""
    return LLVMPIPE_WALK if "llvmpipe" in ctx.info["GL_RENDERER"] else None


def passes(longest: int, take: int | None) -> list[tuple[int, int]]:
    """(skip, take) of the passes that walk lists of up to ``longest`` items ``take`` at a time
    (None: no limit, one pass)."""
    if take is None or longest <= take:
        return [(0, 0xFFFFFFFF)]
    return [(skip, take) for skip in range(0, longest, take)]
