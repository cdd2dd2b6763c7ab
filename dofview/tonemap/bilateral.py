"""``bilateral``: Durand–Dorsey (2002) base/detail tone mapping on log luminance, with a depth term.

    base = bilateral(log2 L),  detail = log2 L − base        (L in display-relative units)
    log2 L_out = min(hi, 0) + c·(base − hi) + detail,   c = min(1, room / (hi − lo))

with :func:`~dofview.tonemap.operator.display_fit`'s room below the top: log2(contrast) for a
scene-referred frame (Durand–Dorsey's target/range), the room down to its own darks for a
display-referred one, so c = 1 — the identity — while the frame fits under white and only a range
above white is compressed. The base range is taken from the luminance percentiles rather than the
base's own min/max (robust and available without another reduction). The bilateral filter is
separable (a horizontal then a vertical pass, each a full bilateral along its line): weights are
spatial Gaussian (σ_s a fraction of the image's longer side) × range Gaussian on log2 L (σ_r) ×
depth Gaussian on log2 camera z (σ_z) — the depth term keeps the base from bleeding across depth
edges, where the thesis saw halos (seed 004 §5.1.3) — × coverage of the neighbour (the
background never enters). Colour is restored by ratio with the exponent s + (1 − s)·c (1 where nothing is compressed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from dofview.tonemap.operator import Operator, by_ratio, check_range, display_fit, luminance

LOG_FLOOR = 1e-30  # log2 of a black pixel is log2(1e-30) ≈ −100: outside every range weight


@dataclass(frozen=True)
class Bilateral(Operator):
    """Durand–Dorsey local operator.

    Attributes:
        sigma_space: spatial σ_s as a fraction of the image's longer side (default 0.02).
        sigma_range: range σ_r in stops of luminance (default 1.33 = 0.4 log10 units).
        sigma_depth: depth σ_z in stops of camera depth (default 0.25); 0 turns the term off.
        contrast: contrast ratio a scene-referred frame's base layer is compressed to (default
            50, not Durand–Dorsey's 5: at 5 the base spans 2.3 stops, the room is lifted to grey
            and 3.4% of the HDR biker's orbit clipped, against 1.2% at 50 — docs/BENCHMARKS.md).
        saturation: colour exponent s in [0.3, 1] (default 0.7).
    """

    sigma_space: float = 0.02
    sigma_range: float = 1.33
    sigma_depth: float = 0.25
    contrast: float = 50.0
    saturation: float = 0.7
    name = "bilateral"
    ranges: ClassVar[dict[str, tuple[float, float]]] = {"sigma_space": (0.005, 0.1), "sigma_range": (0.2, 4.0), "sigma_depth": (0.0, 2.0), "contrast": (2.0, 100.0), "saturation": (0.3, 1.0)}
    glsl = "tonemap_bilateral.glsl"
    adaptive = True
    needs_base = True

    def __post_init__(self) -> None:
        check_range("bilateral spatial sigma (fraction of the image)", self.sigma_space, 1e-3, 0.2)
        check_range("bilateral range sigma (stops)", self.sigma_range, 0.05, 20.0)
        check_range("bilateral depth sigma (stops)", self.sigma_depth, 0.0, 20.0)
        check_range("bilateral base contrast", self.contrast, 1.01, 1e4)
        check_range("bilateral saturation", self.saturation, 0.3, 1.0)

    def spatial(self, width: int, height: int) -> tuple[float, int]:
        """(σ_s in pixels, kernel radius in pixels) for a width × height image."""
        sigma = max(self.sigma_space * max(width, height), 0.5)
        return sigma, math.ceil(2.0 * sigma)

    def filter_uniforms(self, width: int, height: int) -> dict[str, object]:
        sigma, radius = self.spatial(width, height)
        return {"u_sigma_px": sigma, "u_radius": radius, "u_sigma_r": self.sigma_range, "u_sigma_z": self.sigma_depth}

    def uniforms(self, stats, exposure):
        fit = display_fit(stats, exposure, math.log2(self.contrast))
        c = 1.0 if fit.fits else fit.room / (fit.hi - fit.lo)
        return {"u_compression": c, "u_hi": fit.hi, "u_out_hi": fit.out_hi,
                "u_gain_log2": fit.shift - math.log2(exposure),
                "u_saturation": self.saturation + (1.0 - self.saturation) * c}

    def base(self, log_l: np.ndarray, mask: np.ndarray, depth: np.ndarray | None) -> np.ndarray:
        """(H, W) base layer of log2 L: the separable bilateral (twin of bilateral.frag)."""
        h, w = log_l.shape
        sigma, radius = self.spatial(w, h)
        log_z = None
        if depth is not None and self.sigma_depth > 0:
            log_z = np.log2(np.maximum(depth, LOG_FLOOR))
            zmask = depth > 0
        values = log_l
        for axis in (1, 0):
            num = np.zeros_like(values)
            den = np.zeros_like(values)
            n = values.shape[axis]
            for d in range(-radius, radius + 1):
                src = slice(max(d, 0), n + min(d, 0))  # q = p + d inside the image
                dst = slice(max(-d, 0), n - max(d, 0))
                idx_s = (slice(None), src) if axis == 1 else (src, slice(None))
                idx_d = (slice(None), dst) if axis == 1 else (dst, slice(None))
                vq, vp = values[idx_s], values[idx_d]
                wgt = math.exp(-d * d / (2 * sigma * sigma)) * np.exp(-(vq - vp) ** 2 / (2 * self.sigma_range ** 2))
                wgt = wgt * mask[idx_s]
                if log_z is not None:
                    dz = log_z[idx_s] - log_z[idx_d]
                    wgt = wgt * np.where(zmask[idx_d] & zmask[idx_s], np.exp(-dz * dz / (2 * self.sigma_depth ** 2)), 1.0)
                num[idx_d] += wgt * vq
                den[idx_d] += wgt
            with np.errstate(divide="ignore", invalid="ignore"):
                values = np.where(den > 0, num / den, values)
        return values

    def apply(self, rgb, *, stats=None, exposure=1.0, alpha=None, depth=None) -> np.ndarray:
        from dofview.tonemap.stats import covered

        u = self.uniforms(stats, exposure)
        rgb = np.maximum(rgb, 0.0)
        lum = luminance(rgb)
        log_l = np.log2(np.maximum(lum, LOG_FLOOR))
        mask = covered(alpha) if alpha is not None else np.ones(lum.shape, bool)
        base = self.base(log_l, mask, depth)
        base_x = base + u["u_gain_log2"]
        log_out = u["u_out_hi"] + u["u_compression"] * (base_x - u["u_hi"]) + (log_l - base)
        lum_out = np.where(lum > 0, np.exp2(np.minimum(log_out, 64.0)), 0.0)
        return np.clip(by_ratio(rgb, lum, lum_out, u["u_saturation"]), 0.0, 1.0)
