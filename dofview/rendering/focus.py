"""Focus from a rendered depth image: click-to-focus and ``--focus auto``."""

from __future__ import annotations

import numpy as np

from dofview.frame import Frame


def depth_at(frame: Frame, x: float, y: float, radius: int = 2, min_alpha: float = 0.5) -> float | None:
    """Median depth (scene units) in a (2·radius+1)² window around pixel (x, y): the frame's
    focus depth (see :class:`Frame`) where it has one, else its α-weighted mean depth.

    Only well-covered pixels (α > ``min_alpha``) count; None when the window holds none.
    """
    depth = frame.focus_depths
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
    """The median depth under the image centre (a window 10% of the smaller side); where the centre
    is empty (a gap, a ring-shaped object), that of the covered pixels nearest to it
    (:func:`nearest_depth`). None only for a frame with nothing in it."""
    h, w = frame.depth.shape
    radius = max(1, int(0.05 * min(w, h)))
    depth = depth_at(frame, w / 2, h / 2, radius=radius)
    return depth if depth is not None else nearest_depth(frame, w / 2, h / 2, (2 * radius + 1) ** 2)


def nearest_depth(frame: Frame, x: float, y: float, count: int) -> float | None:
    """α-weighted median focus depth of the ``count`` covered pixels nearest to pixel (x, y).

    Covered means α > 0.5, or, in a frame of nothing but haze, α > 0.05; None when no pixel is.
    """
    depth = frame.focus_depths
    for min_alpha in (0.5, 0.05):
        ys, xs = np.nonzero((frame.alpha > min_alpha) & (depth > 0))
        if xs.size:
            break
    else:
        return None
    dist2 = (xs + 0.5 - x) ** 2 + (ys + 0.5 - y) ** 2
    keep = np.argsort(dist2, kind="stable")[:count]
    d = depth[ys[keep], xs[keep]].astype(np.float64)
    a = frame.alpha[ys[keep], xs[keep]].astype(np.float64)
    order = np.argsort(d, kind="stable")
    cum = np.cumsum(a[order])
    return float(d[order][np.searchsorted(cum, 0.5 * cum[-1])])


def depth_range(frame: Frame, lo_pct: float = 2.0, hi_pct: float = 98.0) -> tuple[float, float] | None:
    """(near, far): percentiles of the focus depth over the well-covered pixels (α > 0.5), scene
    units; None when no pixel is. The viewer scales its focus and aperture sliders by it."""
    depth = frame.focus_depths
    d = depth[(frame.alpha > 0.5) & (depth > 0)]
    if d.size == 0:
        return None
    near, far = np.percentile(d, [lo_pct, hi_pct])
    return float(near), float(far)
