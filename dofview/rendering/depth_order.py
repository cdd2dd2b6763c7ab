"""Depth order of Gaussians: front to back by camera-space depth of the means.

Keys are the IEEE bits of float32 depth mapped to monotone uint32, so the order is exact for any
finite depth range (1e-3…1e5 units and beyond) and ties keep their index order (stable), which
keeps equal-depth Gaussians from flickering between frames.
"""

from __future__ import annotations

import numpy as np

from dofview.camera import Camera


def camera_depths(means: np.ndarray, camera: Camera) -> np.ndarray:
    """(N, 3) float32 world means → (N,) float32 camera z, scene units: ((r₀x + r₁y) + r₂z) + t,
    each step rounded to float32 as project.glsl's camera_depth computes it (``precise``), so that
    an order sorted here is sorted by the GPU's depth keys too (the GPU plans its layers:
    rendering/layer_plan.py)."""
    means = np.asarray(means, np.float32)
    r = camera.R[2].astype(np.float32)
    return (means[:, 0] * r[0] + means[:, 1] * r[1]) + means[:, 2] * r[2] + np.float32(camera.T[2])


def order_key(camera: Camera) -> bytes:
    """Bytes that change exactly when the depth order of the scene can change: camera z depends on
    R[2] and T[2] only, so a lens-shifted camera (progressive refinement's passes) or a roll about
    the optical axis keeps the order (Camera.view_key also changes with those)."""
    return np.concatenate([camera.R[2], camera.T[2:]]).tobytes()


def depth_keys(z: np.ndarray) -> np.ndarray:
    """(N,) float32 depths → (N,) uint32 keys in the same order."""
    bits = np.ascontiguousarray(z, dtype=np.float32).view(np.uint32)
    neg = (bits >> 31).astype(bool)
    return np.where(neg, ~bits, bits | np.uint32(0x80000000)).astype(np.uint32)


def argsort_keys(keys: np.ndarray) -> np.ndarray:
    """(N,) uint32 keys → (N,) int64 stable ascending order.

    Two least-significant-digit passes over 16-bit halves: numpy sorts 16-bit keys stably with a
    radix sort, ~4× faster than its stable sort of 32-bit keys (1M keys: ~18 ms vs ~80 ms here),
    and the result is exactly the stable order.
    """
    low = np.argsort((keys & 0xFFFF).astype(np.uint16), kind="stable")
    high = np.argsort((keys[low] >> 16).astype(np.uint16), kind="stable")
    return low[high]


def front_to_back(means: np.ndarray, camera: Camera) -> np.ndarray:
    """(N,) uint32 indices of the Gaussians ordered nearest first (stable for ties)."""
    return argsort_keys(depth_keys(camera_depths(means, camera))).astype(np.uint32)
