"""Sparse differentiable splatting: the trainer's rasteriser at the size of real photos.

The same forward model as :func:`dofview.train.raster.rasterise` (its :func:`project` makes the
splats: EWA projection, CoC-enlarged footprint, normalised opacity, τ-bounded support box), but
composited sparsely, as the compute backend does on the GPU:

1. **Binning**: each splat's support box → the rectangle of 16×16 tiles it touches → one
   (tile, Gaussian) pair per touched tile; a stable sort by tile keeps the depth order within
   each tile, so the pairs are sorted by (tile, depth).
2. **Fragments**: each pair's rows are cut to the chord of the splat's support ellipse inside
   its tile, so only the (pixel, Gaussian) fragments inside are made; a stable sort by pixel
   lays every pixel's list out contiguously, front to back.
3. **Compositing** with segmented scans (a cumulative sum of log(1 − α) per pixel gives each
   fragment's transmittance) and early stop: a fragment after which T would fall below 10⁻⁴
   is not drawn, nor anything behind it (the reference 3DGS rasteriser's rule).
4. **Backward** (:class:`_Composite`): the forward keeps only each chunk's drawn (Gaussian,
   pixel) index lists and the final transmittance T_N per pixel; the backward re-evaluates α
   and T_i per fragment from them, and the colour behind each fragment B_i by a reversed
   segmented scan (the back-to-front walk of the reference backward, done as a scan):
   ∂L/∂α_i = T_i·(c_i·G) − (B_i·G − g_A·T_N)/(1 − α_i), G = ∂L/∂C, g_A = ∂L/∂alpha.
   Nothing of size (pixels × Gaussians) is formed.

Work goes with the pixels each splat covers, not with (tile pixels × Gaussians per tile) as in
the dense path; memory with the fragments of one chunk (:data:`FRAGMENTS_PER_CHUNK`) plus two
indices per drawn fragment.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from dofview.camera import Camera
from dofview.frame import RenderSettings
from dofview.lens import ALPHA_MAX, SUPPORT_MAX, Lens
from dofview.train.raster import TILE, Raster, project

EARLY_STOP = 1e-4  # transmittance below which a pixel stops blending
FRAGMENTS_PER_CHUNK = 1 << 21  # (pixel, Gaussian) fragments built at once: ~20 tensors of this length


@dataclass
class Binning:
    """(tile, Gaussian) pairs sorted by (tile, depth), cut into chunks of whole tiles.

    Attributes:
        gauss: (P,) int64 index of each pair's splat. rect: (P, 4) int64 pixel rectangle
            (x0, y0, x1, y1), inclusive: the splat's support box inside the pair's tile.
        chunks: (start, end) pair ranges, whole tiles, about :data:`FRAGMENTS_PER_CHUNK` fragments each.
    """

    gauss: torch.Tensor
    rect: torch.Tensor
    chunks: list[tuple[int, int]]


def _expand(counts: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """For ``counts`` (K,) ≥ 0: (owner (Σ,) index of each item's row, rank (Σ,) of the item in its row)."""
    owner = torch.repeat_interleave(torch.arange(len(counts), device=counts.device), counts)
    first = torch.cumsum(counts, 0) - counts
    return owner, torch.arange(len(owner), device=counts.device) - first.index_select(0, owner)


def bin_tiles(lo: torch.Tensor, hi: torch.Tensor, width: int, height: int,
              budget: int = FRAGMENTS_PER_CHUNK) -> Binning:
    """Pairs of the splats with support boxes ``lo``..``hi`` ((M, 2) pixels, front to back)."""
    with torch.no_grad():
        # pixels whose centre (x + ½) lies in the box
        p0 = torch.ceil(lo - 0.5).long()
        p1 = torch.floor(hi - 0.5).long()
        p0[:, 0].clamp_(min=0)
        p0[:, 1].clamp_(min=0)
        p1[:, 0].clamp_(max=width - 1)
        p1[:, 1].clamp_(max=height - 1)
        t0, t1 = torch.div(p0, TILE, rounding_mode="floor"), torch.div(p1, TILE, rounding_mode="floor")
        span = torch.where((p1 >= p0).all(1, keepdim=True), t1 - t0 + 1, 0)
        g, k = _expand(span[:, 0] * span[:, 1])
        t0, across = t0.index_select(0, g), span[:, 0].index_select(0, g)
        tx = t0[:, 0] + k % across
        ty = t0[:, 1] + torch.div(k, across, rounding_mode="floor")
        tiles_x = -(-width // TILE)
        tile = ty * tiles_x + tx
        order = torch.sort(tile, stable=True).indices  # g runs front to back: depth order survives
        g, tile, tx, ty = (t.index_select(0, order) for t in (g, tile, tx, ty))
        p0, p1 = p0.index_select(0, g), p1.index_select(0, g)
        corner = torch.stack([tx, ty], 1) * TILE
        rect = torch.cat([torch.maximum(p0, corner), torch.minimum(p1, corner + TILE - 1)], 1)
        frags = (rect[:, 2] - rect[:, 0] + 1) * (rect[:, 3] - rect[:, 1] + 1)
        per_tile = torch.zeros(tiles_x * -(-height // TILE), dtype=torch.long, device=lo.device)
        per_tile.index_add_(0, tile, frags)
        chunk_of_tile = (torch.cumsum(per_tile, 0) - per_tile) // budget
        ends = torch.cumsum(torch.unique_consecutive(chunk_of_tile[tile], return_counts=True)[1], 0).tolist()
    return Binning(gauss=g, rect=rect, chunks=list(zip([0, *ends[:-1]], ends)))


@dataclass
class _Fragments:
    """(pixel, Gaussian) fragments of one chunk, each pixel's run front to back."""

    gauss: torch.Tensor  # (F,) int64 splat
    pixel: torch.Tensor  # (F,) int64 y·W + x
    dx: torch.Tensor  # (F,) pixel centre − mean, px
    dy: torch.Tensor
    alpha: torch.Tensor  # (F,) α after the clamp
    falloff: torch.Tensor  # (F,) exp(−½q), 0 where α is clamped (no gradient through the clamp)
    trans: torch.Tensor  # (F,) transmittance before the fragment
    run: torch.Tensor  # (F,) index of the fragment's pixel run
    runs: int


def _runs(pixel: torch.Tensor) -> torch.Tensor:
    """Run index of each fragment, ``pixel`` sorted."""
    new = torch.ones_like(pixel, dtype=torch.bool)
    new[1:] = pixel[1:] != pixel[:-1]
    return torch.cumsum(new, 0) - 1


def _in_run_cumsum(x: torch.Tensor, run: torch.Tensor, runs: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Inclusive cumulative sums of ``x`` (F,) within each run, and each run's total (float64:
    a global scan's offsets would swamp float32)."""
    x = x.double()
    cs = torch.cumsum(x, 0)
    total = torch.zeros(runs, dtype=torch.float64, device=x.device).index_add_(0, run, x)
    before = torch.cumsum(total, 0) - total
    return cs - before.index_select(0, run), total


def _cull(b: Binning, start: int, end: int, mean2d: torch.Tensor, conic: torch.Tensor, support: torch.Tensor,
          width: int) -> tuple[torch.Tensor, torch.Tensor]:
    """The (Gaussian, pixel) fragments of pairs ``start``..``end`` inside each splat's support
    ellipse, sorted by pixel and, within a pixel, front to back: ((F,) int64, (F,) int64 y·W + x).

    Each pair's rows are cut to the ellipse's chord first (q ≤ r2 solved for x), so only the
    pixels inside, and a rim of rounding, are ever expanded."""
    rect, gauss = b.rect[start:end], b.gauss[start:end]
    pair, k = _expand(rect[:, 3] - rect[:, 1] + 1)
    g = gauss.index_select(0, pair)
    y = rect[:, 1].index_select(0, pair) + k
    a, bb, c = conic.index_select(0, g).unbind(1)
    dy = y.to(conic.dtype) + 0.5 - mean2d[:, 1].index_select(0, g)
    # a·dx² + 2b·dx·dy + c·dy² ≤ r2  ⇔  |dx + b·dy/a| ≤ sqrt(a·r2 − (ac − b²)·dy²)/a
    half = torch.sqrt(torch.clamp(a * support.index_select(0, g) - (a * c - bb * bb) * dy * dy, min=0.0)) / a
    half += 1e-3  # a rim for rounding: the exact test is _evaluate's
    mid = mean2d[:, 0].index_select(0, g) - bb * dy / a - 0.5
    x0 = torch.maximum(torch.ceil(mid - half).long(), rect[:, 0].index_select(0, pair))
    x1 = torch.minimum(torch.floor(mid + half).long(), rect[:, 2].index_select(0, pair))
    row, k = _expand(torch.clamp(x1 - x0 + 1, min=0))
    pixel = y.index_select(0, row) * width + x0.index_select(0, row) + k
    # rows ran (tile, depth, row): a stable sort by pixel keeps each pixel's depth order
    pixel, order = torch.sort(pixel, stable=True)
    return g.index_select(0, row.index_select(0, order)), pixel


def _evaluate(g: torch.Tensor, pixel: torch.Tensor, mean2d: torch.Tensor, conic: torch.Tensor,
              opacity: torch.Tensor, width: int, tau: float, early_stop: bool) -> _Fragments:
    """α, transmittance and runs of fragments ``g``, ``pixel`` (from :func:`_cull`); those
    outside the support or below τ dropped, and with ``early_stop`` those from where T < 10⁻⁴ on."""
    dt = mean2d.dtype
    dx = (pixel % width).to(dt) + 0.5 - mean2d[:, 0].index_select(0, g)
    dy = torch.div(pixel, width, rounding_mode="floor").to(dt) + 0.5 - mean2d[:, 1].index_select(0, g)
    a, b, c = conic.index_select(0, g).unbind(1)
    q = a * dx * dx + 2 * b * dx * dy + c * dy * dy
    falloff = torch.exp(-0.5 * q)
    raw = opacity.index_select(0, g) * falloff
    alpha = torch.clamp(raw, max=ALPHA_MAX)
    keep = (q <= SUPPORT_MAX) & (alpha >= tau) & (alpha > 0)
    run = _runs(pixel)
    runs = _count(run)
    log_keep = torch.where(keep, torch.log1p(-alpha), 0.0)
    after, _ = _in_run_cumsum(log_keep, run, runs)
    if early_stop:
        keep &= after >= math.log(EARLY_STOP)  # a prefix of each run (of the kept ones)
    trans = torch.exp(after - log_keep).to(dt)  # what the kept ones before leave
    falloff = torch.where(raw < ALPHA_MAX, falloff, 0.0)
    if not bool(keep.all()):
        # runs left empty keep their (unused) index: the in-run scans need no contiguous ids
        idx = torch.nonzero(keep).squeeze(1)
        g, pixel, dx, dy, alpha, falloff, trans, run = (
            t.index_select(0, idx) for t in (g, pixel, dx, dy, alpha, falloff, trans, run))
    return _Fragments(gauss=g, pixel=pixel, dx=dx, dy=dy, alpha=alpha, falloff=falloff, trans=trans, run=run, runs=runs)


def _count(run: torch.Tensor) -> int:
    return int(run[-1]) + 1 if len(run) else 0


class _Composite(torch.autograd.Function):
    """(mean2d, conic, opacity, colour) of front-to-back splats → (rgb (H·W, C), alpha (H·W,))."""

    @staticmethod
    def forward(ctx, mean2d, conic, opacity, colour, support, binning: Binning, width: int, height: int,
                tau: float):
        n = width * height
        rgb = torch.zeros(n, colour.shape[1], dtype=colour.dtype, device=colour.device)
        log_final = torch.zeros(n, dtype=torch.float64, device=colour.device)
        lists = []  # each chunk's drawn (Gaussian, pixel) lists: O(fragments), what the backward re-evaluates
        for start, end in binning.chunks:
            f = _evaluate(*_cull(binning, start, end, mean2d, conic, support, width),
                          mean2d, conic, opacity, width, tau, early_stop=True)
            rgb.index_add_(0, f.pixel, (f.alpha * f.trans)[:, None] * colour.index_select(0, f.gauss))
            log_final.index_add_(0, f.pixel, torch.log1p(-f.alpha).double())
            lists.append((f.gauss, f.pixel))
        final = torch.exp(log_final).to(colour.dtype)
        ctx.save_for_backward(mean2d, conic, opacity, colour, final)
        ctx.lists, ctx.width, ctx.tau = lists, width, tau
        return rgb, 1.0 - final

    @staticmethod
    def backward(ctx, grad_rgb, grad_alpha):
        mean2d, conic, opacity, colour, final = ctx.saved_tensors
        g_mean, g_conic = torch.zeros_like(mean2d), torch.zeros_like(conic)
        g_opacity, g_colour = torch.zeros_like(opacity), torch.zeros_like(colour)
        for gauss, pixel in ctx.lists:
            f = _evaluate(gauss, pixel, mean2d, conic, opacity, ctx.width, ctx.tau, early_stop=False)
            grad = grad_rgb.index_select(0, f.pixel)
            weight = f.alpha * f.trans
            g_colour.index_add_(0, f.gauss, weight[:, None] * grad)
            cg = (colour.index_select(0, f.gauss) * grad).sum(1)
            upto, total = _in_run_cumsum(cg * weight, f.run, f.runs)
            behind = (total.index_select(0, f.run) - upto).to(cg.dtype)  # B_i·G: what the splats behind add
            g_cover = grad_alpha.index_select(0, f.pixel) * final.index_select(0, f.pixel)  # g_A·T_N
            g_a = f.trans * cg - (behind - g_cover) / (1.0 - f.alpha)
            g_opacity.index_add_(0, f.gauss, g_a * f.falloff)
            g_q = -0.5 * g_a * f.falloff * opacity.index_select(0, f.gauss)
            cn = conic.index_select(0, f.gauss)
            g_mean.index_add_(0, f.gauss, torch.stack([-2 * g_q * (cn[:, 0] * f.dx + cn[:, 1] * f.dy),
                                                       -2 * g_q * (cn[:, 1] * f.dx + cn[:, 2] * f.dy)], 1))
            g_conic.index_add_(0, f.gauss, torch.stack([g_q * f.dx * f.dx, 2 * g_q * f.dx * f.dy,
                                                        g_q * f.dy * f.dy], 1))
        return g_mean, g_conic, g_opacity, g_colour, None, None, None, None, None


def rasterise_sparse(means: torch.Tensor, quats: torch.Tensor, scales: torch.Tensor, opacities: torch.Tensor,
                     colours: torch.Tensor, camera: Camera, lens: Lens,
                     settings: RenderSettings = RenderSettings(), retain_mean2d: bool = False,
                     sh: torch.Tensor | None = None, budget: int = FRAGMENTS_PER_CHUNK) -> Raster:
    """:func:`dofview.train.raster.rasterise`, composited sparsely (see the module docstring).

    Args:
        means: (N, 3) scene units. quats: (N, 4) (w, x, y, z). scales: (N, 3) scene units, > 0.
        opacities: (N,) in [0, 1]. colours: (N, C) linear (or display) values, any range.
        retain_mean2d: keep the gradient of the projected means (for densification).
        sh: (N, K−1, 3) view-dependent SH coefficients, or None (see :func:`project`).
        budget: fragments per chunk (memory bound; any value gives the same image).
    """
    s = project(means, quats, scales, opacities, colours, camera, lens, settings, sh)
    if retain_mean2d and s.mean2d.requires_grad:
        s.mean2d.retain_grad()
    w, h = camera.width, camera.height
    binning = bin_tiles(s.lo, s.hi, w, h, budget)
    rgb, alpha = _Composite.apply(s.mean2d, s.conic, s.opacity, s.colour, s.support, binning, w, h,
                                   settings.tau)
    return Raster(rgb=rgb.reshape(h, w, -1), alpha=alpha.reshape(h, w), mean2d=s.mean2d, drawn=s.drawn)
