"""Differentiable splatting in plain torch: the trainer's forward model (Cinematic Gaussians Eq. 4–6).

It computes what ``rendering/glsl/quads.vert``/``quads.frag`` and ``reference.py`` compute — EWA
projection with the clamped Jacobian, 0.3 px² low-pass, CoC aperture Gaussian k·R²·I, normalised
opacity, α = min(0.99, o′·exp(−½ dᵀΣ⁻¹d)) cut at τ (or at 3σ when τ = 0), front-to-back
compositing over black — with the lens terms taken from :mod:`dofview.lens` (one definition of
the lens math). The test suite holds it equal to the GL renderer.

Compositing is dense per 16×16 tile: every pixel of a tile against every Gaussian whose support
box reaches the tile, so cost ~ pixels × Gaussians per tile. Meant for small training images.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from dofview.camera import Camera
from dofview.frame import RenderSettings
from dofview.lens import ALPHA_MAX, Lens, blur_footprint, coc, cut_splat, normalise_opacity
from dofview.rendering.reference import sh_view_terms

TILE = 16

@dataclass
class Raster:
    """One rendered view.

    Attributes:
        rgb: (H, W, 3) float32 premultiplied colour over black (same units as the colours given).
        alpha: (H, W) float32 coverage.
        mean2d: (M, 2) pixel positions of the drawn Gaussians (gradients retained when asked).
        drawn: (M,) int64 indices of the drawn Gaussians into the input arrays.
    """

    rgb: torch.Tensor
    alpha: torch.Tensor
    mean2d: torch.Tensor
    drawn: torch.Tensor


def rotations(quats: torch.Tensor) -> torch.Tensor:
    """(N, 4) quaternions (w, x, y, z), any norm → (N, 3, 3) world-from-local rotations."""
    w, x, y, z = torch.nn.functional.normalize(quats, dim=1).unbind(1)
    return torch.stack([
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ], dim=1).reshape(-1, 3, 3)


@dataclass
class Splats:
    """The drawn Gaussians of one view, projected, in front-to-back order (differentiable).

    Attributes:
        mean2d: (M, 2) pixel positions. conic: (M, 3) (a, b, c) of Σ′⁻¹ = [[a, b], [b, c]], px⁻².
        opacity: (M,) normalised opacity o′. colour: (M, 3) the colours given, of these Gaussians.
        support: (M,) no-grad bound r2 on dᵀΣ′⁻¹d where α ≥ τ can hold (≤ 9: 3σ).
        lo, hi: (M, 2) no-grad corners of the support box, pixels (CoC-enlarged).
        drawn: (M,) int64 indices into the input arrays.
    """

    mean2d: torch.Tensor
    conic: torch.Tensor
    opacity: torch.Tensor
    colour: torch.Tensor
    support: torch.Tensor
    lo: torch.Tensor
    hi: torch.Tensor
    drawn: torch.Tensor


def project(means: torch.Tensor, quats: torch.Tensor, scales: torch.Tensor, opacities: torch.Tensor,
            colours: torch.Tensor, camera: Camera, lens: Lens,
            settings: RenderSettings = RenderSettings(), sh: torch.Tensor | None = None) -> Splats:
    """EWA-project Gaussians (activated parameters, world space) for ``camera`` through ``lens``:
    the per-Gaussian half of :func:`rasterise`, shared by the dense and sparse compositors.

    Args:
        means: (N, 3) scene units. quats: (N, 4) (w, x, y, z). scales: (N, 3) scene units, > 0.
        opacities: (N,) in [0, 1]. colours: (N, C) linear (or display) values, any range.
        sh: (N, K−1, C) SH coefficients of degrees 1..3 (K = 4, 9 or 16), or None: then each drawn
            colour is max(colours + Σ Y_j(view dir)·sh_j, 0), view dir = camera centre → mean, as
            the GL renderer evaluates a file's ``SH_C0·f_dc + 0.5`` and ``f_rest``.
    """
    dev, dt = means.device, means.dtype
    R = torch.as_tensor(camera.R, dtype=dt, device=dev)
    T = torch.as_tensor(camera.T, dtype=dt, device=dev)
    fx, fy, cx, cy = camera.fx, camera.fy, camera.cx, camera.cy
    t = means @ R.T + T
    with torch.no_grad():
        front = torch.nonzero(t[:, 2] > settings.near).squeeze(1)
        front = front[torch.argsort(t[front, 2], stable=True)]
    t = t.index_select(0, front)  # (index_select: on the CPU a faster gather and backward than t[front])
    iz = 1.0 / t[:, 2]
    lo_x, lo_y, hi_x, hi_y = camera.frustum_limits()
    tx = torch.clamp(t[:, 0] * iz, lo_x, hi_x)
    ty = torch.clamp(t[:, 1] * iz, lo_y, hi_y)
    a = (fx * iz)[:, None] * (R[0][None] - tx[:, None] * R[2][None])
    c = (fy * iz)[:, None] * (R[1][None] - ty[:, None] * R[2][None])
    M = rotations(quats.index_select(0, front)) * scales.index_select(0, front)[:, None, :]  # Σ = M Mᵀ
    p0 = torch.einsum("ni,nij->nj", a, M)
    p1 = torch.einsum("ni,nij->nj", c, M)
    sxx, sxy, syy = (p0 * p0).sum(1), (p0 * p1).sum(1), (p1 * p1).sum(1)
    det_p = (torch.linalg.cross(p0, p1) ** 2).sum(1)
    radius = coc(iz, lens.aperture, lens.inv_focus)
    sxx, sxy, syy, det, beta = blur_footprint(sxx, sxy, syy, det_p, radius, settings.k)
    o = normalise_opacity(opacities.index_select(0, front), beta, settings.opacity_norm, xp=torch)
    with torch.no_grad():
        kept, _, r2 = cut_splat(o, settings.tau, "drop", xp=torch)
        sel = torch.nonzero(kept & torch.isfinite(det) & (det > 0)).squeeze(1)
    mean2d = torch.stack([fx * t[:, 0] * iz + cx, fy * t[:, 1] * iz + cy], 1).index_select(0, sel)
    sxx, sxy, syy, det = (v.index_select(0, sel) for v in (sxx, sxy, syy, det))
    with torch.no_grad():
        r2 = r2.index_select(0, sel)
        ext = torch.sqrt(r2[:, None] * torch.stack([sxx, syy], 1))  # ≤ 3σ, as quads.vert
    drawn = front.index_select(0, sel)
    colour = colours.index_select(0, drawn)
    if sh is not None and sh.shape[1]:
        centre = torch.as_tensor(camera.centre, dtype=dt, device=dev)
        d = torch.nn.functional.normalize(means.index_select(0, drawn) - centre, dim=1, eps=1e-30)
        colour = torch.clamp(colour + sh_view_terms(sh.index_select(0, drawn), d), min=0.0)
    return Splats(mean2d=mean2d, conic=torch.stack([syy / det, -sxy / det, sxx / det], 1), opacity=o.index_select(0, sel),
                  colour=colour, support=r2, lo=mean2d.detach() - ext, hi=mean2d.detach() + ext,
                  drawn=drawn)


def rasterise(means: torch.Tensor, quats: torch.Tensor, scales: torch.Tensor, opacities: torch.Tensor,
              colours: torch.Tensor, camera: Camera, lens: Lens,
              settings: RenderSettings = RenderSettings(), retain_mean2d: bool = False,
              sh: torch.Tensor | None = None) -> Raster:
    """Render Gaussians (activated parameters, world space) for ``camera`` through ``lens``,
    compositing densely per tile (autograd through every pixel × Gaussian of a tile).

    Args:
        means: (N, 3) scene units. quats: (N, 4) (w, x, y, z). scales: (N, 3) scene units, > 0.
        opacities: (N,) in [0, 1]. colours: (N, 3) linear (or display) values, any range.
        retain_mean2d: keep the gradient of the projected means (for densification).
        sh: (N, K−1, 3) view-dependent SH coefficients, or None (see :func:`project`).
    """
    s = project(means, quats, scales, opacities, colours, camera, lens, settings, sh)
    if retain_mean2d and s.mean2d.requires_grad:
        s.mean2d.retain_grad()
    dev, dt = means.device, means.dtype
    w, h, tau = camera.width, camera.height, settings.tau
    mean2d, conic, o, colour, lo, hi = s.mean2d, s.conic, s.opacity, s.colour, s.lo, s.hi
    rgb = torch.zeros(h, w, 3, dtype=dt, device=dev)
    cover = torch.zeros(h, w, dtype=dt, device=dev)
    for y0 in range(0, h, TILE):
        for x0 in range(0, w, TILE):
            x1, y1 = min(x0 + TILE, w), min(y0 + TILE, h)
            hit = torch.nonzero((hi[:, 0] >= x0) & (lo[:, 0] <= x1) & (hi[:, 1] >= y0) & (lo[:, 1] <= y1)).squeeze(1)
            if hit.numel() == 0:
                continue
            py, px = torch.meshgrid(torch.arange(y0, y1, dtype=dt, device=dev) + 0.5,
                                    torch.arange(x0, x1, dtype=dt, device=dev) + 0.5, indexing="ij")
            dx = px.reshape(-1, 1) - mean2d[hit, 0][None]
            dy = py.reshape(-1, 1) - mean2d[hit, 1][None]
            cn = conic[hit]
            q = cn[:, 0] * dx * dx + 2 * cn[:, 1] * dx * dy + cn[:, 2] * dy * dy
            alpha = torch.clamp(o[hit][None] * torch.exp(-0.5 * q), max=ALPHA_MAX)
            inside = (alpha >= tau) & (q <= 9.0)
            alpha = torch.where(inside, alpha, torch.zeros_like(alpha))
            # transmittance before each splat, as a sum of logs (a cumprod's gradient divides by α)
            log_t = torch.cumsum(torch.log1p(-alpha), dim=1)
            trans = torch.exp(torch.cat([torch.zeros_like(log_t[:, :1]), log_t[:, :-1]], dim=1))
            weight = alpha * trans
            rgb[y0:y1, x0:x1] = (weight @ colour[hit]).reshape(y1 - y0, x1 - x0, 3)
            cover[y0:y1, x0:x1] = (1.0 - torch.exp(log_t[:, -1])).reshape(y1 - y0, x1 - x0)
    return Raster(rgb=rgb, alpha=cover, mean2d=mean2d, drawn=s.drawn)
