"""The antimatter15 ``.splat`` format: 32 bytes per Gaussian, little endian.

position xyz float32 (12 B), scale xyz float32 (12 B, linear), colour RGBA uint8 (4 B: base colour
and opacity × 255), rotation uint8 × 4 (w, x, y, z mapped from [−1, 1] by q·128 + 128). Degree 0
only (view-dependent colour is not stored) and no colour-space metadata: files are sRGB.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from dofview.errors import DofviewError
from dofview.io._common import input_size, report_dropped
from dofview.io.atomic import atomic_output
from dofview.scene import SH_C0, GaussianScene

SPLAT_DTYPE = np.dtype([("position", "<f4", 3), ("scale", "<f4", 3), ("rgba", "u1", 4), ("rot", "u1", 4)])


def read_splat(path: str | Path, progress: Callable[[int, int], None] | None = None) -> GaussianScene:
    """Read a ``.splat`` file into a degree-0 sRGB :class:`GaussianScene`."""
    path = Path(path)
    size = input_size(path)
    if size % SPLAT_DTYPE.itemsize:
        raise DofviewError(f"{path}: size {size} bytes is not a whole number of 32-byte Gaussians "
                           "(cut short, or not a .splat file)")
    try:
        rows = np.fromfile(path, SPLAT_DTYPE)
    except OSError as e:
        raise DofviewError(f"{path}: cannot read ({e.strerror or e})") from None
    n = rows.shape[0]
    rgba = rows["rgba"].astype(np.float32) / 255.0
    q = (rows["rot"].astype(np.float32) - 128.0) / 128.0
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    q = np.where(norm > 1e-12, q / np.maximum(norm, 1e-12), np.array([1, 0, 0, 0], np.float32))
    means, scales = rows["position"], rows["scale"]
    ok = np.isfinite(means).all(1) & np.isfinite(scales).all(1) & (scales > 0).all(1)
    if progress:
        progress(n, n)
    report_dropped(path, ok, "NaN, infinite or non-positive values")
    return GaussianScene(means=means[ok], quats=q[ok], scales=scales[ok], opacities=rgba[ok, 3],
                         sh_dc=(rgba[ok, :3] - 0.5) / SH_C0, colour_space="srgb", name=path.stem)


def write_splat(scene: GaussianScene, path: str | Path) -> None:
    """Write ``scene`` as ``.splat`` (view-dependent SH terms are dropped; 8-bit colour and rotation)."""
    rows = np.zeros(scene.count, SPLAT_DTYPE)
    rows["position"] = scene.means
    rows["scale"] = scene.scales
    colour = np.clip(scene.base_colour(), 0.0, 1.0)
    rows["rgba"][:, :3] = np.round(colour * 255.0)
    rows["rgba"][:, 3] = np.round(np.clip(scene.opacities, 0.0, 1.0) * 255.0)
    rows["rot"] = np.clip(np.round(scene.unit_quats() * 128.0 + 128.0), 0, 255)
    with atomic_output(path) as tmp:
        rows.tofile(tmp)
