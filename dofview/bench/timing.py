"""Frame timing: wall time to completion (glFinish) and the GL timer query's GPU time.

On Mesa llvmpipe the GL timer query brackets only the command submission, not the threaded
rasterisation that glFinish waits for, so its figures are far below the real frame time there;
wall time after glFinish is the meaningful measure on that driver (see :func:`timer_query_covers_raster`).
"""

from __future__ import annotations

import time
from typing import Callable

import moderngl
import numpy as np


class FrameTimer:
    """Times a GL draw call: ``wall_ms, gpu_ms = timer(draw)``."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self._query = ctx.query(time=True)

    def __call__(self, draw: Callable[[], None]) -> tuple[float, float]:
        """Run ``draw`` and wait for the GL to finish; return (wall ms, GL timer query ms)."""
        self.ctx.finish()  # start from an idle pipeline so earlier work is not billed here
        t0 = time.perf_counter()
        with self._query:
            draw()
        self.ctx.finish()
        wall = (time.perf_counter() - t0) * 1e3
        return wall, self._query.elapsed * 1e-6


def timer_query_covers_raster(ctx: moderngl.Context) -> bool:
    """False on drivers whose timer query misses the rasterisation (Mesa llvmpipe/softpipe)."""
    name = str(ctx.info.get("GL_RENDERER", "")).lower()
    return not any(s in name for s in ("llvmpipe", "softpipe", "swrast"))


def median_p90(values: list[float]) -> tuple[float, float]:
    """(median, 90th percentile) of a non-empty list of times."""
    v = np.asarray(values, np.float64)
    return float(np.median(v)), float(np.percentile(v, 90))
