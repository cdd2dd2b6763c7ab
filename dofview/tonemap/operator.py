"""What every tone-mapping operator is: pure data (a frozen dataclass validated in ``__post_init__``)
with a numpy :meth:`Operator.apply`, the twin of its GLSL pass ``rendering/glsl/<glsl>``.

An operator maps exposed linear radiance to display-linear values in [0, 1]; the display gamma,
the background and the exposure multiplier are :class:`~dofview.tonemap.Tonemap`'s. Adaptive
operators read scene statistics (:class:`~dofview.tonemap.stats.Stats`, log2 luminance of the
covered pixels) and work in display-relative units (:func:`display_shift`, 1 = display white):
a display-referred frame's values are display values, exposed as they are; a scene-referred one
has no unit, so its log-average goes to the automatic key first (0 EV is its automatic exposure
and the picture does not depend on the radiance unit). Each then compresses only what lies
beyond the display (:func:`display_fit`): a frame that fits is shown unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from dofview.errors import DofviewError
from dofview.tonemap.stats import LUMINANCE, Stats


def luminance(rgb: np.ndarray) -> np.ndarray:
    """(…, 3) linear RGB → (…) luminance Y."""
    return rgb[..., 0] * LUMINANCE[0] + rgb[..., 1] * LUMINANCE[1] + rgb[..., 2] * LUMINANCE[2]


def by_ratio(rgb: np.ndarray, lum: np.ndarray, lum_out: np.ndarray, saturation: float) -> np.ndarray:
    """Colour restored from a new luminance: (C/L)^s · L_out (TONEMAP.md §Colour); 0 where L = 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(lum[..., None] > 0, np.maximum(rgb, 0.0) / lum[..., None], 0.0)
    return np.power(ratio, saturation) * lum_out[..., None]


MIDDLE_GREY = 0.18  # Reinhard 2002's key of an average scene


def auto_key(stats: Stats) -> float:
    """The key a scene-referred frame's log-average is shown at: Reinhard's automatic estimate
    a = 0.18·4^f, f = (2·log2 L_av − log2 L_lo − log2 L_max)/(log2 L_max − log2 L_lo) (Reinhard 2002,
    "Parameter estimation for photographic tone reproduction"), so a low-key scene (most pixels near
    its dark end, f → −1) keeps a low key 0.045 and a high-key one a high key 0.72. Robust ends:
    the 1st percentile and the log-mean of the brightest 1% (``stats.peak``; not the 99th
    percentile: a lamp lighting a room from under 1% of the pixels still makes the room low-key,
    and its weight grows with its share, not in a jump when it crosses a percentile)."""
    span = stats.peak - stats.lo
    f = min(max((2.0 * stats.key - stats.lo - stats.peak) / span, -1.0), 1.0) if span > 1e-6 else 0.0
    return MIDDLE_GREY * 4.0 ** f


def display_shift(stats: Stats, exposure: float) -> float:
    """log2 of the factor from unexposed linear radiance to display-relative units (1 = display
    white): a display-referred frame's values are display values, so only the exposure multiplier
    applies; a scene-referred one has no unit, so its log-average goes to :func:`auto_key` first."""
    if stats.display_referred:
        return math.log2(exposure)
    return math.log2(exposure * auto_key(stats)) - stats.key


@dataclass(frozen=True)
class DisplayFit:
    """How an exposed frame's luminance range [lo, hi] (log2, display-relative, 0 = white) lies
    against a display of ``stops`` stops: shown from ``out_hi`` = min(hi, 0) down, with ``room``
    stops below ``out_hi`` before the floor. A display-referred frame was made for the display:
    its darks stay where the exposure puts them (floor = its own lo), so only a range above white
    is beyond the display; a scene-referred one has the display's floor −stops. ``fits`` (room ≥
    hi − lo): shown unchanged in display-relative units — the identity for a display-referred frame
    under white."""

    shift: float
    lo: float
    hi: float
    out_hi: float
    room: float

    @property
    def fits(self) -> bool:
        return self.room >= self.hi - self.lo


def display_fit(stats: Stats, exposure: float, stops: float,
                domain: tuple[float, float] | None = None) -> DisplayFit:
    """The :class:`DisplayFit` of [stats.lo, stats.hi] (or of ``domain``, unexposed log2) at
    ``exposure`` (multiplier) on a display of ``stops`` stops."""
    shift = display_shift(stats, exposure)
    lo, hi = (stats.lo, stats.hi) if domain is None else domain
    lo, hi = lo + shift, hi + shift
    floor = lo if stats.display_referred else -stops
    out_hi = min(hi, 0.0)
    # ≥ 0: a scene-referred frame whose top lies below a low-contrast display's floor is flattened, not inverted
    return DisplayFit(shift, lo, hi, out_hi, max(out_hi - floor, 0.0))


def check_range(name: str, value: float, lo: float, hi: float) -> None:
    if not (math.isfinite(value) and lo <= value <= hi):
        raise DofviewError(f"tone mapping: {name} must be in [{lo:g}, {hi:g}], got {value}")


class Operator:
    """Base of the operators in :data:`dofview.tonemap.OPERATORS`.

    Class attributes: ``name`` (the OPERATORS key), ``glsl`` (its pass in rendering/glsl),
    ``adaptive`` (reads statistics), ``needs_cdf`` (the histogram operator's 1-D CDF),
    ``needs_base`` (the bilateral operator's base layer pass), ``ranges`` (slider ranges).
    """

    name: ClassVar[str] = ""
    glsl: ClassVar[str] = ""
    adaptive: ClassVar[bool] = False
    needs_cdf: ClassVar[bool] = False
    needs_base: ClassVar[bool] = False
    ranges: ClassVar[dict[str, tuple[float, float]]] = {}  # slider range of each parameter (viewer)

    def apply(self, rgb: np.ndarray, *, stats: Stats | None = None, exposure: float = 1.0,
              alpha: np.ndarray | None = None, depth: np.ndarray | None = None) -> np.ndarray:
        """(H, W, 3) exposed linear radiance → (H, W, 3) display-linear values in [0, 1].

        ``stats``: the unexposed scene statistics (adaptive operators); ``exposure`` the multiplier
        already applied to ``rgb``; ``alpha`` (H, W) coverage and ``depth`` (H, W) camera z
        (scene units, 0 where nothing was drawn) for operators that use them.
        """
        raise NotImplementedError

    def uniforms(self, stats: Stats | None, exposure: float) -> dict[str, object]:
        """The GLSL pass's operator uniforms (names as in its .glsl file)."""
        return {}

    def generated_glsl(self):
        """For an operator whose GLSL is generated at run time (``aces``): (text put in place of
        ``#include GENERATED`` in its .glsl, lookup tables as textures); None for the others."""
        return

    def require(self) -> None:
        """Check, before a command's work starts, that what this operator runs on is installed
        (``aces``: OpenColorIO); a DofviewError naming the package to install when not."""

    def params(self) -> dict[str, float]:
        """Parameter values by name (the EXR header, the viewer's sliders)."""
        from dataclasses import asdict

        return asdict(self)
