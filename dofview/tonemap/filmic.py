"""``filmic``: Hable's filmic curve (GDC 2010, "Uncharted 2: HDR Lighting"), per channel.

f(x) = (x(Ax + CB) + DE) / (x(Ax + B) + DF) − E/F with A…F his published shoulder/toe constants;
out = f(bias·x) / f(white). A fixed curve: exposure comes only from EV.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from dofview.tonemap.operator import Operator, check_range

A, B, C, D, E, F = 0.15, 0.50, 0.10, 0.20, 0.02, 0.30


def hable(x):
    return (x * (A * x + C * B) + D * E) / (x * (A * x + B) + D * F) - E / F


@dataclass(frozen=True)
class Filmic(Operator):
    """Hable's filmic curve.

    Attributes:
        white: linear white point W (radiance that maps to 1 before the bias), > 1 (default 11.2).
        bias: exposure bias applied before the curve (default 2).
    """

    white: float = 11.2
    bias: float = 2.0
    name = "filmic"
    ranges: ClassVar[dict[str, tuple[float, float]]] = {"white": (2.0, 50.0), "bias": (0.25, 8.0)}
    glsl = "tonemap_filmic.glsl"

    def __post_init__(self) -> None:
        check_range("filmic white point", self.white, 1.0 + 1e-6, 1e4)
        check_range("filmic bias", self.bias, 1e-3, 1e3)

    def apply(self, rgb, *, stats=None, exposure=1.0, alpha=None, depth=None) -> np.ndarray:
        x = np.maximum(rgb, 0.0) * self.bias
        return np.clip(hable(x) / hable(self.white), 0.0, 1.0)

    def uniforms(self, stats, exposure):
        return {"u_white": self.white, "u_bias": self.bias}
