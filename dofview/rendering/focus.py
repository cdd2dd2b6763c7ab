"""Focus from a rendered depth image: click-to-focus and ``--focus auto``."""

from __future__ import annotations

import numpy as np

from dofview.frame import Frame


def depth_at(frame: Frame, x: float, y: float, radius: int = 2, min_alpha: float = 0.5) -> float | None:
    """Median depth (scene units) in a (2·radius+1)² window around pixel (x, y): the frame's
    focus depth (see :class:`Frame`) where it has one, else its α-weighted mean depth.

    Only well-covered pixels (α > ``min_alpha``) count; None when the window holds none.
    """
    depth = frame.depth if frame.focus_depth is None else frame.focus_depth
    h, w = depth.shape
    xi, yi = int(np.floor(x)), int(np.floor(y))
    x0, x1 = max(xi - radius, 0), min(xi + radius + 1, w)
    y0, y1 = max(yi - radius, 0), min(yi + radius + 1, h)
    if x0 >= x1 or y0 >= y1:
        return None
    d = depth[y0:y1, x0:x1]
    a = frame.alpha[y0:y1, x0:x1]
    vals = d[(a > min_alpha) & (d > 0)]
    return float(np.median(vals)) if vals.size else None


def auto_focus(frame: Frame) -> float | None:
    """The median depth under the image centre (a window 10% of the smaller side)."""
    h, w = frame.depth.shape
    return depth_at(frame, w / 2, h / 2, radius=max(1, int(0.05 * min(w, h))))
