"""Helpers shared by the readers of quantised distribution formats (.spz, .compressed.ply, .sog):
turning decoded attribute arrays into a :class:`GaussianScene`, and unsigned-normalised unpacking.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dofview.io._common import report_dropped
from dofview.scene import GaussianScene

LOG_SCALE_LIMIT = 87.0  # exp stays finite and normal in float32 inside ±87


def unorm(packed: np.ndarray, shift: int, bits: int) -> np.ndarray:
    """(N,) float64 in [0, 1]: the ``bits``-wide unsigned field at ``shift`` of each packed integer."""
    top = (1 << bits) - 1
    return ((packed.astype(np.uint32) >> np.uint32(shift)) & np.uint32(top)).astype(np.float64) / top


def quats_from_smallest_three(largest: np.ndarray, others: np.ndarray) -> np.ndarray:
    """(N, 4) float64 unit quaternions from "smallest three" codes.

    Args:
        largest: (N,) int, index 0–3 of the dropped (largest, non-negative) component.
        others: (N, 3) float64, the other three components in index order.
    """
    n = largest.shape[0]
    q = np.zeros((n, 4))
    rest = np.ones((n, 4), bool)
    rest[np.arange(n), largest] = False
    q[rest] = others.reshape(-1)
    q[np.arange(n), largest] = np.sqrt(np.maximum(0.0, 1.0 - np.sum(others * others, axis=1)))
    return q


def scene_from_arrays(path: Path, means: np.ndarray, quats_wxyz: np.ndarray, log_scales: np.ndarray,
                      opacities: np.ndarray, sh_dc: np.ndarray, sh_rest: np.ndarray | None,
                      name: str | None = None) -> GaussianScene:
    """An activated, sRGB :class:`GaussianScene` from decoded attributes.

    Args:
        means: (N, 3) scene units. quats_wxyz: (N, 4), any length (normalised here; a zero one
        becomes the identity). log_scales: (N, 3) natural-log standard deviations. opacities: (N,)
        in [0, 1]. sh_dc: (N, 3). sh_rest: (N, K−1, 3) or None. name: the scene's name (default:
        the file name up to its first dot).

    Gaussians with a NaN or infinite value (a corrupt bound or codebook entry) are dropped with one
    :class:`DofviewWarning` that counts them, as the .ply reader does (all of them: a DofviewError).
    """
    scene, ok = scene_and_finite(means, quats_wxyz, log_scales, opacities, sh_dc, sh_rest, name or path.name.split(".")[0])
    report_dropped(path, ok)
    if not ok.all():
        scene = scene.subset(ok)
    return scene


def scene_and_finite(means: np.ndarray, quats_wxyz: np.ndarray, log_scales: np.ndarray, opacities: np.ndarray,
                     sh_dc: np.ndarray, sh_rest: np.ndarray | None, name: str) -> tuple[GaussianScene, np.ndarray]:
    """Every Gaussian of the decoded attributes (as :func:`scene_from_arrays` takes them) as an
    sRGB scene, and (N,) bool which of them are finite (the others hold NaN or infinite values)."""
    q = np.asarray(quats_wxyz, np.float64)
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    q = np.where(norm > 1e-30, q / np.maximum(norm, 1e-300), np.array([1.0, 0.0, 0.0, 0.0]))
    scales = np.exp(np.clip(log_scales, -LOG_SCALE_LIMIT, LOG_SCALE_LIMIT))
    ok = (np.isfinite(means).all(1) & np.isfinite(q).all(1) & np.isfinite(log_scales).all(1)
          & np.isfinite(opacities) & np.isfinite(sh_dc).all(1))
    if sh_rest is not None:
        ok &= np.isfinite(sh_rest).all((1, 2))
    scene = GaussianScene(means=means, quats=q, scales=scales, opacities=np.clip(opacities, 0.0, 1.0),
                          sh_dc=sh_dc, sh_rest=sh_rest, colour_space="srgb", name=name)
    return scene, ok
