"""``pbr-neutral``: Khronos PBR Neutral tone mapper (Khronos 3D Commerce specification, 2024).

Keeps base colours under about 0.76 unchanged apart from a small toe offset and compresses highlights
towards white with a hue-preserving desaturation. A fixed curve: exposure comes only from EV.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dofview.tonemap.operator import Operator

START_COMPRESSION = 0.8 - 0.04
DESATURATION = 0.15


@dataclass(frozen=True)
class PbrNeutral(Operator):
    """Khronos PBR Neutral; no parameters."""

    name = "pbr-neutral"
    glsl = "tonemap_pbr_neutral.glsl"

    def apply(self, rgb, *, stats=None, exposure=1.0, alpha=None, depth=None) -> np.ndarray:
        c = np.maximum(np.asarray(rgb, np.float64), 0.0)
        x = c.min(axis=-1, keepdims=True)
        offset = np.where(x < 0.08, x - 6.25 * x * x, 0.04)
        c = c - offset
        peak = c.max(axis=-1, keepdims=True)
        d = 1.0 - START_COMPRESSION
        new_peak = 1.0 - d * d / (peak + d - START_COMPRESSION)
        with np.errstate(divide="ignore", invalid="ignore"):
            scaled = np.where(peak > 0, c * (new_peak / peak), 0.0)
        g = 1.0 - 1.0 / (DESATURATION * (peak - new_peak) + 1.0)
        compressed = scaled * (1.0 - g) + new_peak * g
        return np.clip(np.where(peak < START_COMPRESSION, c, compressed), 0.0, 1.0)
