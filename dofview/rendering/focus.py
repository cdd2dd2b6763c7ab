"""Focus from a rendered depth image: click-to-focus and ``--focus auto``; the depths in view that
the sliders follow, and those ``--blur`` is measured on."""

from __future__ import annotations

import numpy as np

from dofview.frame import Frame
from dofview.tonemap import Tonemap


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


DETAIL_RADIUS = 4
"""Half-width (px at the measuring width, the reference width for ``--blur``) of the neighbourhood a
pixel's detail is measured against: fine detail, which a few pixels of blur change. (Measured at
the scale of the blur itself, 16 px for 2 % of 800, a scan's soft far shell counts again.)"""
DETAIL_LEVELS = 2.0
"""A pixel shows detail when its display luminance differs from its neighbourhood's mean by more
than this many levels of the 8-bit image: there a few pixels of blur visibly change the picture."""
ONE_DEPTH_RATIO = 2.0
"""A pixel shows one depth when its α-weighted mean depth is within this factor of its focus depth
(1 / mean 1/z; the two agree only for a single depth): a faint near splat over a far backdrop has
neither, and the detail it shows is the near splat's, nearer than either. (On tap.spz any factor
from 1.2 to 5 gives the same aperture within 3 %; without the test the backdrop's fringes set it.)
A neighbour this much nearer is an occluder, whose silhouette the detail beside it belongs to."""
MIN_DETAIL_SHARE = 0.005
"""Fewer detailed pixels than this share of the covered ones (a featureless frame): the covered
pixels are used instead."""


def blur_span(frame: Frame, tonemap: Tonemap | None = None, lo_pct: float = 2.0,
              hi_pct: float = 98.0) -> tuple[float, float] | None:
    """(near, far): the depths ``--blur R`` gives its largest blur to, scene units, from a pinhole
    frame: percentiles of the focus depth over the covered pixels (α > 0.5) that show detail at one
    depth (:data:`DETAIL_LEVELS` of the display image ``tonemap`` makes, default clip at 0 EV;
    :data:`ONE_DEPTH_RATIO`) — where a blur is seen. A smooth backdrop (a scan's far shell, a sky,
    a plain wall) blurs without changing the picture, so it does not set the scale: on
    tests/data/tap.spz (800×600) the scan's far shell (100–240 units) covers 44 % of the frame and
    none of its pixels with detail at one depth (5 % of the frame), and the blur goes to the wall
    around the tap (1.04–1.36 units) instead of the shell (1.08–235).
    An edge counts at the depth of its nearer side. A frame with almost no detail
    (:data:`MIN_DETAIL_SHARE`) is measured on all its covered pixels, as :func:`depth_range`; None
    when no pixel is covered."""
    depth = frame.focus_depths
    covered = (frame.alpha > 0.5) & (depth > 0)
    if not covered.any():
        return None
    luma = frame.display(tonemap).astype(np.float32) @ np.float32([0.2126, 0.7152, 0.0722])
    detail = np.abs(luma - _box_mean(luma, DETAIL_RADIUS)) > DETAIL_LEVELS
    # detail in or beside a pixel of mixed depths may be that pixel's, whose depth is unknown: left out
    mixed = covered & (frame.depth > ONE_DEPTH_RATIO * depth)
    one_depth = _window_min(np.where(mixed, 0.0, 1.0), DETAIL_RADIUS) > 0
    seen = covered & detail & one_depth
    if np.count_nonzero(seen) < MIN_DETAIL_SHARE * np.count_nonzero(covered):
        return depth_range(frame, lo_pct, hi_pct)
    # an edge is detail on both of its sides, but it belongs to the nearer surface (the occluder's
    # silhouette; a backdrop blurred behind it leaves it as it is): beside a surface more than
    # ONE_DEPTH_RATIO nearer, a pixel's detail is taken at that surface's depth
    nearest = _window_min(np.where(covered, depth, np.inf), DETAIL_RADIUS)
    depth = np.where(nearest * ONE_DEPTH_RATIO < depth, nearest, depth)
    near, far = np.percentile(depth[seen], [lo_pct, hi_pct])
    return float(near), float(far)


def _window_min(image: np.ndarray, radius: int) -> np.ndarray:
    """(H, W) minimum of each pixel's (2·radius + 1)² neighbourhood (edges repeated)."""
    from numpy.lib.stride_tricks import sliding_window_view

    k = 2 * radius + 1
    padded = np.pad(image, radius, mode="edge")
    rows = sliding_window_view(padded, k, axis=0).min(-1)
    return sliding_window_view(rows, k, axis=1).min(-1)


def _box_mean(image: np.ndarray, radius: int) -> np.ndarray:
    """(H, W) mean of each pixel's (2·radius + 1)² neighbourhood, edges repeated."""
    k = 2 * radius + 1
    padded = np.pad(image.astype(np.float64), radius, mode="edge")
    table = np.pad(padded.cumsum(0).cumsum(1), ((1, 0), (1, 0)))
    return (table[k:, k:] - table[:-k, k:] - table[k:, :-k] + table[:-k, :-k]) / (k * k)
