"""``aces-fit``: the ACES look as Narkowicz's published fit of the ACES 1.0 RRT + sRGB ODT (2015).

f(x) = x(2.51x + 0.03) / (x(2.43x + 0.59) + 0.14), per channel, on 0.6·x (his exposure match to
ACES's mid-grey); a fixed curve: exposure comes only from the EV setting. Needs no library;
``aces`` is the real ACES 2.0 output transform through OpenColorIO.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dofview.tonemap.operator import Operator

PRE_SCALE = 0.6


@dataclass(frozen=True)
class AcesFit(Operator):
    """Narkowicz's fitted ACES curve per channel; no parameters."""

    name = "aces-fit"
    glsl = "tonemap_aces_fit.glsl"

    def apply(self, rgb, *, stats=None, exposure=1.0, alpha=None, depth=None) -> np.ndarray:
        x = np.maximum(rgb, 0.0) * PRE_SCALE
        return np.clip(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)
