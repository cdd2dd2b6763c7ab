"""``reinhard05``: the Reinhard–Devlin photoreceptor (2005), per channel, with robust statistics.

On key-normalised input C = 0.18·e·C_scene / 2^key (e the exposure, so EV acts after normalising):

    I_local,i = c_a·C_i + (1 − c_a)·L            I_global,i = c_a·C_i,av + (1 − c_a)·L_av
    I_a,i     = l_a·I_local,i + (1 − l_a)·I_global,i
    C'_i      = C_i / (C_i + (e^(−b)·I_a,i)^m)

with the averages C_i,av, L_av the log-averages (robust; the paper's arithmetic means move with
one hot pixel), m = 0.3 + 0.7·k^1.4, k = (log L_hi − log L_av)/(log L_hi − log L_lo) from the
1st/99th percentiles (not min/max), and the result divided by the curve at the 99th percentiles of
L and of each channel, so the 99th percentile maps to 1 (the thesis normalises by the output's min and max, which one hot pixel moves;
seed 004 §5.1.5, TONEMAP.md; stretching from L_lo as well over-saturated low-range frames).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from dofview.tonemap.operator import Operator, check_range, luminance

DEGENERATE_SPAN = 1e-3  # a grey curve span below this (a constant frame) is not normalised
MIDDLE_GREY = 0.18  # the key is normalised to it (Reinhard 2002's a), so b = 0 gives a mid-grey key


@dataclass(frozen=True)
class Reinhard05(Operator):
    """Reinhard–Devlin photoreceptor.

    Attributes:
        b: brightness b, −8…8 (default 0; larger is brighter).
        m: contrast m in (0, 1], or 0 = automatic from the statistics (default).
        c_a: chromatic adaptation c_a in [0, 1] (0: adapt to luminance; 1: per channel). Default
            0.5, not the paper's 0: at 0 a saturated colour's channel (lamp.ply's blue cube) runs
            to 1 and 7.4% of lamp view 0 clipped, against 1.2% at 0.5.
        l_a: light adaptation l_a in [0, 1] (1: to the pixel itself; 0: to the scene average).
    """

    b: float = 0.0
    m: float = 0.0
    c_a: float = 0.5
    l_a: float = 1.0
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

    def _top(self, stats, m: float) -> float:
        """The curve's output at the 99th percentiles: the brightest channel of a pixel whose
        luminance and channels sit at their 99th percentiles (key-normalised, unexposed)."""
        lum = MIDDLE_GREY * 2.0 ** (stats.hi - stats.key)
        top = 0.0
        for c_hi, c_key in zip(stats.channel_hi, stats.channel_key):
            c = MIDDLE_GREY * 2.0 ** (c_hi - stats.key)
            i_global = self.c_a * MIDDLE_GREY * 2.0 ** (c_key - stats.key) + (1.0 - self.c_a) * MIDDLE_GREY
            ia = self.l_a * (self.c_a * c + (1.0 - self.c_a) * lum) + (1.0 - self.l_a) * i_global
            den = c + (math.exp(-self.b) * ia) ** m
            top = max(top, c / den if den > 0 else 0.0)
        return top

    def uniforms(self, stats, exposure):
        m = self.contrast(stats)
        v_lo, v_hi = 0.0, self._top(stats, m)
        if v_hi - v_lo < DEGENERATE_SPAN:
            v_lo, v_hi = 0.0, 1.0
        cav = [exposure * MIDDLE_GREY * 2.0 ** (k - stats.key) for k in stats.channel_key]
        return {"u_inv_key": MIDDLE_GREY * 2.0 ** -stats.key, "u_m": m, "u_b": self.b, "u_c_a": self.c_a, "u_l_a": self.l_a,
                "u_c_av": tuple(cav), "u_l_av": exposure * MIDDLE_GREY, "u_v_lo": v_lo, "u_v_hi": v_hi}

    def apply(self, rgb, *, stats=None, exposure=1.0, alpha=None, depth=None) -> np.ndarray:
        u = self.uniforms(stats, exposure)
        c = np.maximum(rgb, 0.0) * u["u_inv_key"]
        lum = luminance(c)[..., None]
        i_local = self.c_a * c + (1.0 - self.c_a) * lum
        i_global = self.c_a * np.asarray(u["u_c_av"]) + (1.0 - self.c_a) * u["u_l_av"]
        ia = self.l_a * i_local + (1.0 - self.l_a) * i_global
        den = c + np.power(math.exp(-self.b) * ia, u["u_m"])
        with np.errstate(divide="ignore", invalid="ignore"):
            out = np.where(den > 0, c / den, 0.0)
        return np.clip((out - u["u_v_lo"]) / (u["u_v_hi"] - u["u_v_lo"]), 0.0, 1.0)
