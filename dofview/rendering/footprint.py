"""Each Gaussian's footprint on the screen, on the CPU: the projection the CPU reference composites
(reference.py) and the sliced mode's numpy plan measures (slices.screen_boxes), float64, twin of
glsl/project.glsl; and the box of the part of a footprint that lies in a rectangle, twin of
glsl/plan_stats.comp's."""

from __future__ import annotations

import numpy as np

from dofview.camera import Camera
from dofview.frame import RenderSettings
from dofview.lens import (
    Lens,
    blur_footprint,
    coc,
    cut_splat,
    disk_peak_and_area,
    disk_support,
    kernel_shape,
    normalise_opacity,
)
from dofview.scene import GaussianScene

CLIP_INFLATE = 1.001
"""The support bound r2 is widened by this factor before a footprint is clipped: where the ellipse
is tangent to a side of the rectangle its extent is √(r2 − q), whose slope is unbounded there, so
rounding (float32 on the GPU) could otherwise cut a pixel the splat draws."""


def project(scene: GaussianScene, camera: Camera, lens: Lens, settings: RenderSettings) -> dict[str, np.ndarray]:
    """Per-Gaussian screen-space quantities, float64, for the Gaussians in front of the near plane.

    Returns a dict of arrays over the M kept Gaussians (front to back): ``idx`` (M,), ``mean2d``
    (M, 2) pixels, ``cov`` (M, 3) the blurred 2D covariance (xx, xy, yy) px² and ``det`` (M,) its
    determinant (from the projection's factors: no cancellation), ``opacity`` (M,) o′
    (o′/F(0) for a disk splat), ``depth`` (M,) camera z, ``r2`` (M,) the support bound on dᵀΣ⁻¹d,
    ``shape`` (M,) the kernel shape s (1: Gaussian).
    """
    t = camera.world_to_camera(scene.means)
    keep = t[:, 2] > settings.near
    idx = np.nonzero(keep)[0]
    idx = idx[np.argsort(t[idx, 2], kind="stable")]
    t = t[idx]
    fx, fy, cx, cy = camera.fx, camera.fy, camera.cx, camera.cy
    iz = 1.0 / t[:, 2]
    lo_x, lo_y, hi_x, hi_y = camera.frustum_limits()
    tx = np.clip(t[:, 0] * iz, lo_x, hi_x)
    ty = np.clip(t[:, 1] * iz, lo_y, hi_y)
    R = camera.R
    a = (fx * iz)[:, None] * (R[0][None] - tx[:, None] * R[2][None])
    c = (fy * iz)[:, None] * (R[1][None] - ty[:, None] * R[2][None])
    M = scene.rotation_matrices()[idx] * scene.scales[idx].astype(np.float64)[:, None, :]  # Σ = M Mᵀ
    p0 = np.einsum("ni,nij->nj", a, M)
    p1 = np.einsum("ni,nij->nj", c, M)
    sxx, sxy, syy = (p0 * p0).sum(1), (p0 * p1).sum(1), (p1 * p1).sum(1)
    det_p = (np.cross(p0, p1) ** 2).sum(1)
    radius = coc(iz, lens.aperture, lens.inv_focus)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        sxx, sxy, syy, det, beta = blur_footprint(sxx, sxy, syy, det_p, radius, settings.k)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        shape = kernel_shape(beta, det, radius, settings.k) if settings.kernel == "disk" else np.ones_like(det)
        shape = np.where(np.isfinite(shape), shape, 1.0)
    disk = shape < 1.0
    f0, area = disk_peak_and_area(np.where(disk, shape, 0.5))
    o = normalise_opacity(scene.opacities[idx].astype(np.float64), beta * np.where(disk, area, 1.0),
                          settings.opacity_norm)
    with np.errstate(divide="ignore", invalid="ignore"):
        kept, o, r2 = cut_splat(o, settings.tau, settings.cut)
        r2 = np.where(disk, disk_support(o, settings.tau, np.where(disk, shape, 0.5)), r2)
    o = np.where(disk, o / f0, o)
    ok = np.isfinite(det) & (det > 0) & kept
    mean2d = np.stack([fx * t[:, 0] * iz + cx, fy * t[:, 1] * iz + cy], axis=1)
    sel = np.nonzero(ok)[0]
    return {
        "idx": idx[sel], "mean2d": mean2d[sel], "cov": np.stack([sxx, sxy, syy], 1)[sel], "det": det[sel],
        "opacity": o[sel], "depth": t[sel, 2], "r2": r2[sel], "shape": shape[sel],
    }


def _band_extent(p: np.ndarray, q: np.ndarray, sxx: np.ndarray, sxy: np.ndarray, syy: np.ndarray, det: np.ndarray,
                 r2: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) of the first coordinate over the ellipse {d: dᵀΣ⁻¹d ≤ r2} about (p, q), Σ =
    ((sxx, sxy), (sxy, syy)) of determinant ``det``, where its second lies in [lo, hi] (all (M,)):
    +inf, −inf where it never does. Its boundary is x = p + k(y − q) ± h·√(r2 − (y − q)²/syy),
    k = sxy/syy, h² = det/syy (not sxx − sxy·k: for a needle at the lens that difference of
    numbers near 10⁸ px² cancels in float32): the + side is concave in y, so its largest value
    over the band is at the ellipse's own rightmost point if the band holds it, else at the
    band's end nearest it (the − side likewise)."""
    ey = np.sqrt(r2 * syy)
    a, b = np.maximum(lo, q - ey), np.minimum(hi, q + ey)
    k = sxy / syy
    h = np.sqrt(det / syy)
    turn = sxy * np.sqrt(r2 / sxx)  # y − q of the rightmost point (−turn: the leftmost)

    def side(y: np.ndarray, sign: float) -> np.ndarray:
        return p + k * (y - q) + sign * h * np.sqrt(np.maximum(r2 - (y - q) ** 2 / syy, 0.0))

    high = side(np.clip(q + turn, a, b), 1.0)
    low = side(np.clip(q - turn, a, b), -1.0)
    empty = a > b
    return np.where(empty, np.inf, low), np.where(empty, -np.inf, high)


def clip_boxes(mean2d: np.ndarray, cov: np.ndarray, det: np.ndarray, r2: np.ndarray,
               rect: tuple[float, float, float, float], rounds: int = 2) -> np.ndarray:
    """(M, 4) float64 per footprint (centres ``mean2d`` (M, 2) px, covariances ``cov`` (M, 3) (xx,
    xy, yy) px² of determinants ``det`` (M,), support ``r2`` (M,), widened by
    :data:`CLIP_INFLATE`) a box (x0, y0, x1, y1) px
    holding the part of it inside ``rect`` (x0, y0, x1, y1): the x-range of the ellipse over the
    box's y-range, then the y-range over its x-range, ``rounds`` times from the rectangle. A
    superset of that part, exact where it is convex enough (one round is the box of the ellipse
    cut by two bands); x0 > x1 where the ellipse misses the rectangle. A splat near the lens is an
    ellipse thousands of pixels wide whose box covers the frame while it draws in a corner of it,
    or nowhere."""
    p, q = mean2d[:, 0], mean2d[:, 1]
    sxx, sxy, syy = cov[:, 0], cov[:, 1], cov[:, 2]
    r2 = r2 * CLIP_INFLATE
    x0, y0, x1, y1 = (np.full(len(p), float(v)) for v in rect)
    with np.errstate(invalid="ignore"):  # a footprint that missed: infinite bands, NaN sides, still missing
        for _ in range(rounds):
            lo, hi = _band_extent(p, q, sxx, sxy, syy, det, r2, y0, y1)
            x0, x1 = np.maximum(x0, lo), np.minimum(x1, hi)
            lo, hi = _band_extent(q, p, syy, sxy, sxx, det, r2, x0, x1)
            y0, y1 = np.maximum(y0, lo), np.minimum(y1, hi)
    return np.stack([x0, y0, x1, y1], 1)
