"""``histogram``: Ward Larson's histogram adjustment (1997) with a linear ceiling, solved exactly.

On log2 luminance in display-relative units (:func:`~dofview.tonemap.operator.display_fit`; 0 =
display white), between the robust lo and hi (1st/99th percentiles, TONEMAP.md), WARD_BINS bins
of density p_b and width Δb:

- the curve's slope d log L_d / d log L is min(1, λ·p_b/Δb): histogram equalisation limited by
  Ward's linear ceiling (contrast is never exaggerated), λ chosen so that the slopes add up to the
  display's room below the top (``DisplayFit.room``: log2(ld_max/ld_min) for a scene-referred frame;
  for a display-referred one the room down to its own darks, so only what lies above white is
  compressed). This is the fixed point of Ward's iterated ceiling (t = T·Δb/log c with T the
  trimmed total), solved by bisection instead of a count of passes that stops early (a varying
  count made seams, seed 004 §6.2.2) — continuous in the statistics and the exposure;
- if the range fits the room (the ceiling never binds) the slope is 1: the identity, Ward's
  linear mapping; if even slope 1 on every occupied bin falls short, empty bins get the rest;
- the top maps to min(hi, 0), slope 1 outside [lo, hi]; colour by ratio (C/L)^s·L_d with s from
  1 (slope 1, nothing compressed) to ``saturation`` (slope 0).

The curve is a (WARD_BINS + 1)-entry table of log2 L_d at the bin edges, on the GPU a 1-D texture,
built per exposure from the statistics' CDF (a table lookup: it depends on the exposure).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from dofview.tonemap.operator import Operator, by_ratio, check_range, display_fit, luminance

BISECTIONS = 60  # on log λ: λ to ~1e-9 relative, far below a display step


@dataclass(frozen=True)
class Histogram(Operator):
    """Ward Larson histogram adjustment.

    Attributes:
        ld_min, ld_max: display luminance range, cd/m² (default 0.3…300: a scene-referred frame's
            room is log2(1000) ≈ 10 stops; only the ratio is used).
        saturation: colour exponent s in [0.3, 1] where the curve compresses fully (default 0.7,
            against over-saturation); 1 where it does not compress.
    """

    ld_min: float = 0.3
    ld_max: float = 300.0
    saturation: float = 0.7
    name = "histogram"
    ranges: ClassVar[dict[str, tuple[float, float]]] = {"ld_min": (0.01, 10.0), "ld_max": (50.0, 2000.0), "saturation": (0.3, 1.0)}
    glsl = "tonemap_histogram.glsl"
    adaptive = True
    needs_cdf = True

    def __post_init__(self) -> None:
        check_range("histogram display minimum (cd/m²)", self.ld_min, 1e-4, 1e4)
        check_range("histogram display maximum (cd/m²)", self.ld_max, self.ld_min * 1.01, 1e6)
        check_range("histogram saturation", self.saturation, 0.3, 1.0)

    @staticmethod
    def slopes(density: np.ndarray, width: float, room: float) -> np.ndarray:
        """(N,) slopes min(1, λ·p/Δb) of bins of ``density`` (sums to 1) and ``width`` stops whose
        sum times the width is ``room`` stops (< N·width: the range does not fit)."""
        occupied = density > 0
        if occupied.sum() * width <= room:  # even slope 1 everywhere occupied falls short
            rest = (room - occupied.sum() * width) / max((~occupied).sum() * width, 1e-30)
            return np.where(occupied, 1.0, min(rest, 1.0))
        lo, hi = math.log(max(room, 1e-30)), math.log(width / density[occupied].min())
        for _ in range(BISECTIONS):
            mid = 0.5 * (lo + hi)
            if np.minimum(1.0, math.exp(mid) * density / width).sum() * width > room:
                hi = mid
            else:
                lo = mid
        return np.minimum(1.0, math.exp(0.5 * (lo + hi)) * density / width)

    def curve(self, stats, exposure: float) -> np.ndarray:
        """(WARD_BINS + 1,) log2 display luminance at the bin edges of [cdf_lo, cdf_hi] (exposed,
        display-relative) at ``exposure`` (multiplier)."""
        fit = display_fit(stats, exposure, math.log2(self.ld_max / self.ld_min), (stats.cdf_lo, stats.cdf_hi))
        density = np.diff(np.asarray(stats.cdf, np.float64))
        width = (fit.hi - fit.lo) / len(density)
        slope = np.ones_like(density) if fit.fits else self.slopes(density, width, fit.room)
        return fit.out_hi - np.concatenate([np.cumsum((slope * width)[::-1])[::-1], [0.0]])

    def uniforms(self, stats, exposure):
        fit = display_fit(stats, exposure, math.log2(self.ld_max / self.ld_min), (stats.cdf_lo, stats.cdf_hi))
        return {"u_gain_log2": fit.shift - math.log2(exposure), "u_dom_lo": fit.lo, "u_dom_hi": fit.hi,
                "u_saturation": self.saturation, "u_cdf_n": len(stats.cdf) - 1}

    def apply(self, rgb, *, stats=None, exposure=1.0, alpha=None, depth=None) -> np.ndarray:
        u = self.uniforms(stats, exposure)
        table = self.curve(stats, exposure)
        n, lo, hi = u["u_cdf_n"], u["u_dom_lo"], u["u_dom_hi"]
        rgb = np.maximum(rgb, 0.0)
        lum = luminance(rgb)
        log_l = np.log2(np.maximum(lum, 1e-30)) + u["u_gain_log2"]
        pos = (log_l - lo) / (hi - lo) * n
        i = np.clip(np.floor(pos), 0, n - 1).astype(np.int64)
        f = pos - i
        inside = (pos >= 0) & (pos <= n)
        slope = np.where(inside, (table[i + 1] - table[i]) / ((hi - lo) / n), 1.0)
        log_out = np.where(pos < 0, table[0] + log_l - lo,
                           np.where(pos > n, table[n] + log_l - hi, table[i] * (1.0 - f) + table[i + 1] * f))
        lum_out = np.where(lum > 0, np.exp2(np.minimum(log_out, 64.0)), 0.0)
        s = self.saturation + (1.0 - self.saturation) * np.clip(slope, 0.0, 1.0)
        return np.clip(by_ratio(rgb, lum, lum_out, s[..., None]), 0.0, 1.0)
