"""Thin-lens ground truth: the average of pinhole renders over the lens disk (accumulation buffer).

For a lens point (u, v) within radius D/2 the camera centre moves by (u, v) in its own x/y and the
principal point by (f_x·u/d_f, f_y·v/d_f), so the plane z = d_f stays fixed; a point at depth z then
covers a disk of radius ½·f_x·D·|1/z − 1/d_f| = R(z) with A = f_x·D. Averaging is done on the
linear images, as light adds on a sensor.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from dofview.camera import Camera
from dofview.frame import Frame, depth_from_weighted
from dofview.lens import Lens

GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))


def lens_samples(n: int) -> np.ndarray:
    """(n, 2) float64 points of the unit disk, evenly spread (Vogel's sunflower spiral)."""
    i = np.arange(n) + 0.5
    r = np.sqrt(i / n)
    th = i * GOLDEN_ANGLE
    return np.stack([r * np.cos(th), r * np.sin(th)], axis=1)


def accumulate(render_pinhole: Callable[[Camera], Frame], camera: Camera, lens: Lens, samples: int = 256,
               progress: Callable[[int, int], None] | None = None, points: np.ndarray | None = None) -> Frame:
    """Average ``samples`` pinhole renders over the aperture of ``lens`` (diameter A / f_x).

    ``render_pinhole(camera)`` must render with aperture 0: the GL renderer and the CPU reference
    both fit. ``progress(i, n)`` is called after each sample. ``points``: (samples, 2) points of
    the unit disk to use instead of :func:`lens_samples` (e.g. bench.refinement.disk_sequence).
    """
    if samples < 1:
        raise ValueError("samples must be ≥ 1")
    radius = 0.5 * lens.diameter(camera.fx)
    pts = lens_samples(samples) if points is None else np.asarray(points, np.float64)[:samples]
    rgba = depth_w = None
    for i, (u, v) in enumerate(pts * radius):
        f = render_pinhole(camera.lens_shifted(u, v, lens.focus))
        if rgba is None:
            rgba = np.zeros(f.rgba.shape, np.float64)
            depth_w = np.zeros(f.depth.shape, np.float64)
            encoded = f.encoded
        rgba += f.rgba
        depth_w += f.depth * f.rgba[..., 3]
        if progress:
            progress(i + 1, samples)
    rgba /= samples
    depth_w /= samples
    return Frame(rgba=rgba.astype(np.float32), depth=depth_from_weighted(depth_w, rgba[..., 3]), encoded=encoded)
