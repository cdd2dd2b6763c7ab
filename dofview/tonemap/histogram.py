"""``histogram``: Ward Larson's histogram adjustment (1997) with a linear ceiling.

On log2 luminance between the robust lo and hi (1st/99th percentiles, TONEMAP.md), WARD_BINS bins:

- ceiling (linear, not perceptual): clip each bin to t = T·Δb / log c, Δb the bin width, T the
  current total, c = L_dmax/L_dmin the display contrast (the thesis prints this inverted);
- a FIXED number of such passes (a count that varies between views made seams, seed 004 §6.2.2);
  if T falls below the tolerance, or the scene's range fits the display, map linearly instead;
- log L_d = log L_dmin + (log L_dmax − log L_dmin)·P(log L) with P the CDF (the thesis prints the
  bracket without logs), display-linear L_d / L_dmax, colour by ratio (C/L)^s·L_d.

The CDF is a (WARD_BINS + 1)-entry table, piecewise linear in log L; on the GPU a 1-D texture.
Exposure shifts log L before the lookup, so EV acts after the adaptation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from dofview.tonemap.operator import Operator, by_ratio, check_range, luminance


def lookup(table: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Piecewise-linear table lookup at x ∈ [0, 1] (clamped), as tonemap_histogram.glsl does it."""
    n = len(table) - 1
    pos = np.clip(x, 0.0, 1.0) * n
    i = np.minimum(np.floor(pos).astype(np.int64), n - 1)
    f = pos - i
    return table[i] * (1.0 - f) + table[i + 1] * f


@dataclass(frozen=True)
class Histogram(Operator):
    """Ward Larson histogram adjustment.

    Attributes:
        ld_min, ld_max: display luminance range, cd/m² (default 0.3…300, contrast 1000:1).
        saturation: colour exponent s in [0.3, 1] (default 0.7, against over-saturation).
        passes: ceiling passes, fixed (default 4, the thesis's).
        tolerance: the fraction of the original total below which the scene is mapped linearly.
    """

    ld_min: float = 0.3
    ld_max: float = 300.0
    saturation: float = 0.7
    passes: int = 4
    tolerance: float = 0.025
    name = "histogram"
    ranges: ClassVar[dict[str, tuple[float, float]]] = {"ld_min": (0.01, 10.0), "ld_max": (50.0, 2000.0), "saturation": (0.3, 1.0), "passes": (0, 8), "tolerance": (0.0, 0.2)}
    glsl = "tonemap_histogram.glsl"
    adaptive = True
    needs_cdf = True

    def __post_init__(self) -> None:
        check_range("histogram display minimum (cd/m²)", self.ld_min, 1e-4, 1e4)
        check_range("histogram display maximum (cd/m²)", self.ld_max, self.ld_min * 1.01, 1e6)
        check_range("histogram saturation", self.saturation, 0.3, 1.0)
        check_range("histogram ceiling passes", self.passes, 0, 32)
        check_range("histogram tolerance", self.tolerance, 0.0, 1.0)

    def cdf(self, hist: np.ndarray, lo: float, hi: float) -> tuple[np.ndarray, bool]:
        """(WARD_BINS,) counts over log2 [lo, hi] → (CDF table (WARD_BINS + 1,), map linearly)."""
        h = np.asarray(hist, np.float64).copy()
        total0 = h.sum()
        log_c = math.log2(self.ld_max / self.ld_min)
        delta_b = (hi - lo) / len(h)
        linear = total0 <= 0 or (hi - lo) <= log_c
        for _ in range(self.passes):
            t = h.sum()
            if t <= self.tolerance * total0:
                linear = True
                break
            h = np.minimum(h, t * delta_b / log_c)
        table = np.concatenate([[0.0], np.cumsum(h)])
        return (table / table[-1] if table[-1] > 0 else np.linspace(0.0, 1.0, len(table))), linear

    def uniforms(self, stats, exposure):
        return {"u_cdf_lo": stats.cdf_lo, "u_cdf_hi": stats.cdf_hi,
                "u_linear": bool(stats.linear), "u_hi": stats.hi, "u_contrast": self.ld_min / self.ld_max,
                "u_saturation": self.saturation, "u_cdf_n": len(stats.cdf) - 1}

    def apply(self, rgb, *, stats=None, exposure=1.0, alpha=None, depth=None) -> np.ndarray:
        u = self.uniforms(stats, exposure)
        rgb = np.maximum(rgb, 0.0)
        lum = luminance(rgb)
        if stats.linear:
            lum_out = np.minimum(lum / 2.0 ** u["u_hi"], 1.0)
        else:
            log_l = np.log2(np.maximum(lum, 1e-30))
            p = lookup(stats.cdf, (log_l - stats.cdf_lo) / (stats.cdf_hi - stats.cdf_lo))
            lum_out = np.where(lum > 0, np.power(u["u_contrast"], 1.0 - p), 0.0)
        return np.clip(by_ratio(rgb, lum, lum_out, self.saturation), 0.0, 1.0)
