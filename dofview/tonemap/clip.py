"""``clip``: Eq. 7's display transform, exposure then a hard clip to [0, 1] (the default)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dofview.tonemap.operator import Operator


@dataclass(frozen=True)
class Clip(Operator):
    """Clip exposed linear radiance to [0, 1]; no parameters (exposure and gamma are Tonemap's).

    Keeps a display-encoded scene exactly as trained at 0 EV, γ 2.2.
    """

    name = "clip"
    glsl = "tonemap_clip.glsl"

    def apply(self, rgb, *, stats=None, exposure=1.0, alpha=None, depth=None) -> np.ndarray:
        return np.clip(rgb, 0.0, 1.0)
