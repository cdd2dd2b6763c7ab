"""``reinhard05``: the Reinhard–Devlin photoreceptor (2005), compressing only what the display
cannot show.

Input in display-relative units x = g·e·C (:func:`~dofview.tonemap.operator.display_shift`: g = 1
for a display-referred frame, whose values are display values; the automatic key over the
log-average for a scene-referred one, so a low-key scene stays low-key). W = max(1, x at the 99th
percentile of the brightest channel) is the white: 1 when the frame fits under display white.
With ν = 1 − 1/W, the share of the top that lies beyond the display:

    I_local,i = c_a·x_i + (1 − c_a)·L          I_global,i = c_a·x_i,av + (1 − c_a)·L_av
    I_a,i     = l_a·I_local,i + (1 − l_a)·I_global,i
    σ_i       = σ_0·(e^(−b)·I_a,i / L_av)^(m·ν),    σ_0 = 1/ν = W/(W − 1)
    x'_i      = x_i / (x_i + σ_i),   shown as x'_i / x'(W)  (a grey pixel at W, adapted alike)

At the global adaptation level σ = σ_0 gives the curve x·W/(x·(W − 1) + W): slope 1 at black (the
darks keep their display values), W → 1 the identity (a frame that fits is shown as it is; ν = 0
switches the adaptation off too), W → ∞ Reinhard's x/(1 + x) with σ_i = (e^(−b)·I_a,i/L_av)^m, the
paper's semi-saturation on key-normalised input. m = 0.3 + 0.7·k^1.4, k = (log L_hi − log L_av) /
(log L_hi − log L_lo) from the 1st/99th percentiles (seed 004 §5.1.5, robust: no min/max).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from dofview.tonemap.operator import Operator, check_range, display_shift, luminance

FITS = 1e-4  # ν below this: the frame fits under white, shown unchanged (σ_0 = 1/ν would overflow)


@dataclass(frozen=True)
class Reinhard05(Operator):
    """Reinhard–Devlin photoreceptor.

    Attributes:
        b: brightness b, −8…8 (default 0; larger is brighter where the range is compressed).
        m: contrast m in (0, 1], or 0 = automatic from the statistics (default).
        c_a: chromatic adaptation c_a in [0, 1] (0: adapt to luminance, the default; 1: per channel).
        l_a: light adaptation l_a in [0, 1] (1: to the pixel itself; 0: to the scene average, the
            default, not the paper's 1: adapting to the pixel lifts its darks by (1/x)^(m·ν) —
            the black leather of tests/data/biker.spz turned silver — where only the range beyond
            white needs compressing).
    """

    b: float = 0.0
    m: float = 0.0
    c_a: float = 0.0
    l_a: float = 0.0
    name = "reinhard05"
    ranges: ClassVar[dict[str, tuple[float, float]]] = {"b": (-8.0, 8.0), "m": (0.0, 1.0), "c_a": (0.0, 1.0), "l_a": (0.0, 1.0)}
    glsl = "tonemap_reinhard05.glsl"
    adaptive = True

    def __post_init__(self) -> None:
        check_range("reinhard05 brightness b", self.b, -8.0, 8.0)
        check_range("reinhard05 contrast m (0 = auto)", self.m, 0.0, 1.0)
        check_range("reinhard05 chromatic adaptation c_a", self.c_a, 0.0, 1.0)
        check_range("reinhard05 light adaptation l_a", self.l_a, 0.0, 1.0)

    def contrast(self, stats) -> float:
        if self.m > 0:
            return self.m
        span = stats.hi - stats.lo
        k = min(max((stats.hi - stats.key) / span, 0.0), 1.0) if span > 1e-6 else 0.0
        return 0.3 + 0.7 * k ** 1.4

    def uniforms(self, stats, exposure):
        shift = display_shift(stats, exposure)
        gain = 2.0 ** (shift - math.log2(exposure))  # the exposed input is already ×e
        top = max(stats.hi, *stats.channel_hi) + shift
        white = max(1.0, 2.0 ** min(top, 126.0))
        nu = 1.0 - 1.0 / white
        l_av = 2.0 ** (stats.key + shift)
        u = {"u_gain": gain, "u_identity": nu < FITS, "u_c_a": self.c_a, "u_l_a": self.l_a, "u_l_av": l_av,
             "u_c_av": tuple(2.0 ** (k + shift) for k in stats.channel_key), "u_sigma0": 1.0, "u_power": 0.0,
             "u_adapt": math.exp(-self.b) / l_av, "u_white_v": 1.0}
        if nu >= FITS:
            power = self.contrast(stats) * nu
            sigma_w = (u["u_adapt"] * (self.l_a * white + (1.0 - self.l_a) * l_av)) ** power / nu
            u.update(u_sigma0=1.0 / nu, u_power=power, u_white_v=white / (white + sigma_w))
        return u

    def apply(self, rgb, *, stats=None, exposure=1.0, alpha=None, depth=None) -> np.ndarray:
        u = self.uniforms(stats, exposure)
        x = np.maximum(rgb, 0.0) * u["u_gain"]
        if u["u_identity"]:
            return np.clip(x, 0.0, 1.0)
        lum = luminance(x)[..., None]
        i_local = self.c_a * x + (1.0 - self.c_a) * lum
        i_global = self.c_a * np.asarray(u["u_c_av"]) + (1.0 - self.c_a) * u["u_l_av"]
        ia = self.l_a * i_local + (1.0 - self.l_a) * i_global
        sigma = u["u_sigma0"] * np.power(u["u_adapt"] * ia, u["u_power"])
        den = x + sigma  # 0 only for a black channel adapted to itself (l_a = 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            v = np.where(den > 0, x / den, 0.0)
        return np.clip(v / u["u_white_v"], 0.0, 1.0)
