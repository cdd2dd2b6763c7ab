"""What every tone-mapping operator is: pure data (a frozen dataclass validated in ``__post_init__``)
with a numpy :meth:`Operator.apply`, the twin of its GLSL pass ``rendering/glsl/<glsl>``.

An operator maps exposed linear radiance to display-linear values in [0, 1]; the display gamma,
the background and the exposure multiplier are :class:`~dofview.tonemap.Tonemap`'s. Adaptive
operators read scene statistics (:class:`~dofview.tonemap.stats.Stats`, log2 luminance of the
covered pixels) and apply the exposure *after* normalising by them, so 0 EV is their automatic
exposure and the picture does not depend on the scene's arbitrary radiance unit.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from dofview.errors import DofviewError

if TYPE_CHECKING:
    from dofview.tonemap.stats import Stats

LUMINANCE = (0.2126, 0.7152, 0.0722)  # Y of linear Rec.709 RGB


def luminance(rgb: np.ndarray) -> np.ndarray:
    """(…, 3) linear RGB → (…) luminance Y."""
    return rgb[..., 0] * LUMINANCE[0] + rgb[..., 1] * LUMINANCE[1] + rgb[..., 2] * LUMINANCE[2]


def by_ratio(rgb: np.ndarray, lum: np.ndarray, lum_out: np.ndarray, saturation: float) -> np.ndarray:
    """Colour restored from a new luminance: (C/L)^s · L_out (TONEMAP.md §Colour); 0 where L = 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(lum[..., None] > 0, np.maximum(rgb, 0.0) / lum[..., None], 0.0)
    return np.power(ratio, saturation) * lum_out[..., None]


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

    def params(self) -> dict[str, float]:
        """Parameter values by name (the EXR header, the viewer's sliders)."""
        from dataclasses import asdict

        return asdict(self)
