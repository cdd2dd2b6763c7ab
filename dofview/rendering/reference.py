"""CPU reference renderer: plain numpy, float64, exact per-pixel front-to-back compositing.

The one deliberate twin of the GL renderer, kept plain and slow, for small images in tests.
No quads and no key quantisation: every pixel centre is tested against every Gaussian whose
support can reach its tile (the support's axis-aligned box is exact, so no contribution is lost),
and the depth order is an exact float64 stable sort of the means' camera depths.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TypeVar

import numpy as np

from dofview.camera import Camera
from dofview.deep import TRANSMITTANCE_MIN, DeepFrame, DeepSettings
from dofview.frame import Frame, RenderSettings, depth_from_weighted
from dofview.lens import ALPHA_MAX, SUPPORT_MAX, Lens, disk_profile
from dofview.rendering.deep_sliced import SliceCapture, layer_depths
from dofview.rendering.footprint import project
from dofview.rendering.slices import (
    Aperture,
    LensCell,
    SliceRule,
    from_blend_space,
    plan_frame,
    rule_for,
    sliced_image,
)
from dofview.scene import SH_C0, GaussianScene
from dofview.tonemap import decode

Array = TypeVar("Array")  # a numpy array or a torch tensor
_C1 = 0.4886025119029199
_C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792, 0.5462742152960396)
_C3 = (-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
       -0.4570457994644658, 1.445305721320277, -0.5900435899266435)


def sh_view_terms(sh: Array, d: Array) -> Array:
    """Σ_j Y_j(d)·sh_j over SH degrees 1..3 (basis and signs of sh.glsl / the reference 3DGS code).

    Plain arithmetic and slicing only, so numpy arrays and torch tensors both work (the trainer
    evaluates its colours with this, differentiably).

    Args:
        sh: (M, K−1, C) coefficients, K = (degree + 1)² ∈ {4, 9, 16}; a degree is used whole.
        d: (M, 3) unit view directions (eye → mean).
    Returns:
        (M, C) the view-dependent colour terms.
    """
    deg = {3: 1, 8: 2, 15: 3}[sh.shape[1]]
    x, y, z = d[:, 0:1], d[:, 1:2], d[:, 2:3]
    c = _C1 * (-y * sh[:, 0] + z * sh[:, 1] - x * sh[:, 2])
    if deg > 1:
        xx, yy, zz = x * x, y * y, z * z
        c = c + (_C2[0] * x * y * sh[:, 3] + _C2[1] * y * z * sh[:, 4]
                 + _C2[2] * (2 * zz - xx - yy) * sh[:, 5] + _C2[3] * x * z * sh[:, 6]
                 + _C2[4] * (xx - yy) * sh[:, 7])
    if deg > 2:
        c = c + (_C3[0] * y * (3 * xx - yy) * sh[:, 8] + _C3[1] * x * y * z * sh[:, 9]
                 + _C3[2] * y * (4 * zz - xx - yy) * sh[:, 10]
                 + _C3[3] * z * (2 * zz - 3 * xx - 3 * yy) * sh[:, 11]
                 + _C3[4] * x * (4 * zz - xx - yy) * sh[:, 12] + _C3[5] * z * (xx - yy) * sh[:, 13]
                 + _C3[6] * x * (xx - 3 * yy) * sh[:, 14])
    return c


def sh_colour(scene: GaussianScene, eye: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """(M, 3) float64 colour max(SH(view dir) + 0.5, 0) of the Gaussians ``idx`` seen from ``eye``."""
    c = SH_C0 * scene.sh_dc[idx].astype(np.float64) + 0.5
    if scene.sh_degree > 0:
        d = scene.means[idx].astype(np.float64) - eye
        d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-30)
        c = c + sh_view_terms(scene.sh_rest[idx].astype(np.float64), d)
    return np.maximum(c, 0.0)


def render_reference(scene: GaussianScene, camera: Camera, lens: Lens,
                     settings: RenderSettings = RenderSettings(dof="splat"), tile: int = 16,
                     margins: bool = False) -> Frame | tuple[Frame, np.ndarray]:
    """Render ``scene`` on the CPU with per-splat depth of field (``settings.dof`` is not read:
    :func:`render_reference_sliced` is the sliced mode). Cost ~ pixels × Gaussians per tile: keep
    images small.

    With ``margins=True`` also returns an (H, W) bool mask of the pixels where some Gaussian sits
    within 1e-5 (relative) of a cut (α = τ, or dᵀΣ⁻¹d = 9 when τ = 0): there a float32 renderer
    may legitimately decide the other way, so comparisons can leave those pixels out.
    """
    blend, sums, near_cut = _blend(scene, camera, lens, settings, tile, margins)
    encoded = scene.colour_space == "srgb" and not settings.blend_linear
    frame = _frame(blend, sums, encoded)
    return (frame, near_cut) if margins else frame


def _frame(blend: np.ndarray, sums: np.ndarray, encoded: bool) -> Frame:
    """A Frame from the blend-space premultiplied colour (H, W, 4) and the depth sums (H, W, 4)
    (Σw·z, Σw/z, 0, Σw) of a blend."""
    rgba = from_blend_space(blend, encoded)
    inv = depth_from_weighted(sums[..., 1], sums[..., 3])
    focus = np.where(inv > 0, 1.0 / np.maximum(inv, 1e-30), 0.0).astype(np.float32)
    return Frame(rgba=rgba, depth=depth_from_weighted(sums[..., 0], sums[..., 3]), encoded=encoded,
                 focus_depth=focus)


def _blend(scene: GaussianScene, camera: Camera, lens: Lens, settings: RenderSettings, tile: int,
           margins: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The exact front-to-back blend: (H, W, 4) float64 premultiplied colour in the blend space
    and coverage, (H, W, 4) float64 depth sums (Σw·z, Σw/z, 0, Σw), and the near-cut mask of
    :func:`render_reference`."""
    w, h = camera.width, camera.height
    pr, colour = _projected(scene, camera, lens, settings)
    out = np.zeros((h, w, 4))
    sums = np.zeros((h, w, 4))
    near_cut = np.zeros((h, w), bool)
    for (x0, y0, x1, y1), hit, alpha, edge in _tile_alphas(pr, w, h, settings.tau, tile, margins):
        if edge is not None:
            near_cut[y0:y1, x0:x1] = edge.reshape(y1 - y0, x1 - x0)
        trans = np.cumprod(1.0 - alpha, axis=1)
        weight = alpha * np.concatenate([np.ones((alpha.shape[0], 1)), trans[:, :-1]], axis=1)
        rgb = weight @ colour[hit]
        a = 1.0 - trans[:, -1]
        z = weight @ np.stack([pr["depth"][hit], 1.0 / pr["depth"][hit]], 1)
        out[y0:y1, x0:x1, :3] = rgb.reshape(y1 - y0, x1 - x0, 3)
        out[y0:y1, x0:x1, 3] = a.reshape(y1 - y0, x1 - x0)
        sums[y0:y1, x0:x1, :2] = z.reshape(y1 - y0, x1 - x0, 2)
    sums[..., 3] = out[..., 3]
    return out, sums, near_cut


def _projected(scene: GaussianScene, camera: Camera, lens: Lens,
               settings: RenderSettings) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """:func:`project`'s footprints and the (M, 3) float64 colours in the blend space (decoded
    when blending linearly)."""
    pr = project(scene, camera, lens, settings)
    colour = sh_colour(scene, camera.centre, pr["idx"])
    return pr, decode(colour) if settings.blend_linear else colour


def _tile_alphas(pr: dict[str, np.ndarray], w: int, h: int, tau: float, tile: int, margins: bool):
    """Per ``tile``-pixel square of the w × h image that some footprint of ``pr`` reaches: its
    (x0, y0, x1, y1) pixels, the (M,) indices into ``pr`` of the footprints reaching it (front to
    back), their (P, M) float64 alphas at its P pixel centres (row-major; 0 where cut by τ or the
    support) and, when ``margins``, a (P,) bool mask of the pixels where some alpha sits within
    1e-5 (relative) of a cut (else None)."""
    sxx, sxy, syy = pr["cov"].T
    det = sxx * syy - sxy * sxy
    conic = np.stack([syy / det, -sxy / det, sxx / det], 1)
    ext = np.sqrt(pr["r2"][:, None] * np.stack([sxx, syy], 1))
    shape = pr["shape"]
    disk = shape < 1.0
    sig = np.sqrt(shape)
    qmax = np.where(disk, (2.0 * np.sqrt(np.maximum(1.0 - shape, 0.0)) + 3.0 * sig) ** 2, SUPPORT_MAX)
    lo, hi = pr["mean2d"] - ext, pr["mean2d"] + ext
    for y0 in range(0, h, tile):
        for x0 in range(0, w, tile):
            x1, y1 = min(x0 + tile, w), min(y0 + tile, h)
            hit = np.nonzero((hi[:, 0] >= x0) & (lo[:, 0] <= x1) & (hi[:, 1] >= y0) & (lo[:, 1] <= y1))[0]
            if hit.size == 0:
                continue
            px, py = np.meshgrid(np.arange(x0, x1) + 0.5, np.arange(y0, y1) + 0.5)
            dx = px.reshape(-1, 1) - pr["mean2d"][hit, 0][None]
            dy = py.reshape(-1, 1) - pr["mean2d"][hit, 1][None]
            cn = conic[hit]
            q = cn[:, 0] * dx * dx + 2 * cn[:, 1] * dx * dy + cn[:, 2] * dy * dy
            dk = disk[hit][None]
            profile = np.exp(-0.5 * q)
            if dk.any():
                profile = np.where(dk, disk_profile(q, np.where(dk, shape[hit][None], 0.5)), profile)
            alpha = np.minimum(ALPHA_MAX, pr["opacity"][hit][None] * profile)
            qm = qmax[hit][None]
            edge = None
            if margins:
                near = np.abs(q - qm) <= 1e-5 * qm
                if tau > 0:
                    near |= np.abs(alpha - tau) <= 1e-5 * tau
                edge = near.any(axis=1)
            yield (x0, y0, x1, y1), hit, np.where((alpha >= tau) & (q <= qm), alpha, 0.0), edge


def render_reference_deep(scene: GaussianScene, camera: Camera, lens: Lens = Lens(1.0, 0.0),
                          settings: RenderSettings = RenderSettings(dof="splat"), deep: DeepSettings = DeepSettings(),
                          tile: int = 16) -> DeepFrame:
    """The deep image of :func:`render_reference`'s blend (the twin of ``Renderer.deep``): each
    pixel's contributions front to back, grouped by the rule of :mod:`dofview.deep` (a
    contribution at depth z joins the open sample started at z₀ while z ≤ z₀·(1 + tolerance), or
    when the pixel has used up its ``cap``), the walk ending where the transmittance falls below
    :data:`~dofview.deep.TRANSMITTANCE_MIN`; samples in linear light, telescoped through the decode
    of an encoded blend (see dofview.deep)."""
    w, h = camera.width, camera.height
    pr, colour = _projected(scene, camera, lens, settings)
    linear = decode if scene.colour_space == "srgb" and not settings.blend_linear else np.asarray
    reach = 1.0 + deep.tolerance
    found: list[tuple[np.ndarray, ...]] = []  # (pixel, index in pixel, rgba, depth) per emission
    for (x0, y0, x1, y1), hit, alpha, _ in _tile_alphas(pr, w, h, settings.tau, tile, False):
        tw, npx = x1 - x0, alpha.shape[0]
        pixel = (y0 + np.arange(npx) // tw) * w + x0 + np.arange(npx) % tw
        rgb, rgb0 = np.zeros((npx, 3)), np.zeros((npx, 3))
        trans, trans0, z0, z1 = np.ones(npx), np.ones(npx), np.zeros(npx), np.zeros(npx)
        count, opened = np.zeros(npx, np.int64), np.zeros(npx, bool)

        def close(m: np.ndarray) -> None:
            found.append((pixel[m], count[m].copy(),
                          np.column_stack([(linear(rgb[m]) - linear(rgb0[m])) / trans0[m, None],
                                           1.0 - trans[m] / trans0[m]]),
                          np.column_stack([z0[m], z1[m]])))
            count[m] += 1
            opened[m] = False

        depth = pr["depth"][hit]
        for j in np.nonzero(alpha.any(axis=0))[0]:
            a, z = alpha[:, j], depth[j]
            live = (a > 0) & (trans >= TRANSMITTANCE_MIN)
            if not live.any():
                continue
            ends = live & opened & (z > z0 * reach) & (count + 1 < deep.cap)
            if ends.any():
                close(ends)
            starts = live & ~opened
            rgb0[starts], trans0[starts], z0[starts], z1[starts] = rgb[starts], trans[starts], z, z
            opened |= starts
            rgb[live] += (a[live] * trans[live])[:, None] * colour[hit[j]]
            trans[live] *= 1.0 - a[live]
            z1[live] = np.maximum(z1[live], z)
        if opened.any():
            close(opened.copy())
    if not found:
        return DeepFrame(np.zeros((h, w), np.int64), np.zeros((0, 4)), np.zeros((0, 2)))
    pix, k, rgba, zz = (np.concatenate(parts) for parts in zip(*found))
    order = np.lexsort((k, pix))
    return DeepFrame(np.bincount(pix, minlength=w * h).reshape(h, w), rgba[order], zz[order])


def render_reference_sliced(scene: GaussianScene, camera: Camera, lens: Lens,
                            settings: RenderSettings = RenderSettings(dof="sliced"), tile: int = 16,
                            rule: SliceRule | None = None, cell: LensCell | None = None) -> Frame:
    """The sliced mode (rendering/sliced.py) on the CPU: each layer of slices.plan_layers, taken
    from this reference's own float64 depth order, blended by :func:`_blend` as a pinhole with the
    frame's τ (the huge-CoC front and back layers with the lens and ``settings``), then blurred and
    composited by slices.sliced_image with ``rule`` (default: the GL path's, slices.rule_for) and
    the kernel of ``cell`` (default: the whole aperture of ``settings``)."""
    layers = _sliced_layers(scene, camera, lens, settings, tile, rule, cell)
    if layers is None:  # nothing in front of the near plane
        return render_reference(scene, camera, lens, replace(settings, dof="splat"), tile)
    colour, sums = sliced_image(*layers.args)
    sums[..., 2] = 0.0  # (the visibility the layers kept there)
    return _frame(colour, sums, layers.encoded)


def render_reference_sliced_deep(scene: GaussianScene, camera: Camera, lens: Lens,
                                 settings: RenderSettings = RenderSettings(dof="sliced"),
                                 deep: DeepSettings = DeepSettings(), tile: int = 16) -> DeepFrame:
    """The twin of ``Renderer.deep`` in the sliced mode with an aperture: :func:`render_reference_sliced`'s
    layers, their composite captured after each (slices.sliced_image's ``capture``) and made samples
    by rendering/deep_sliced.py as the GL path's are."""
    layers = _sliced_layers(scene, camera, lens, settings, tile, None, None)
    w, h = camera.width, camera.height
    if layers is None:
        return DeepFrame(np.zeros((h, w), np.int64), np.zeros((0, 4)), np.zeros((0, 2)))
    capture = SliceCapture(w, h, layers.args[5])
    colour, _ = sliced_image(*layers.args, capture=capture.whole)
    depths = layer_depths(layers.args[1], layers.order, scene.means, camera, settings.near)
    return capture.deep(colour, depths, deep, layers.encoded)


@dataclass
class _SlicedLayers:
    """The layers :func:`render_reference_sliced` blends: ``args`` slices.sliced_image's (layers,
    plan, lens, rule, cell, guard, edges), ``order`` the draw order they cut, ``encoded`` the blend space."""

    args: tuple
    order: np.ndarray
    encoded: bool


def _sliced_layers(scene: GaussianScene, camera: Camera, lens: Lens, settings: RenderSettings, tile: int,
                   rule: SliceRule | None, cell: LensCell | None) -> _SlicedLayers | None:
    """The sliced mode's layers as the CPU blends them (None: nothing in front of the near plane)."""
    rule = rule or rule_for(settings.blades)
    z = scene.means.astype(np.float64) @ camera.R[2].astype(np.float64) + float(camera.T[2])
    order = np.argsort(z, kind="stable")
    cell = cell or Aperture(settings.blades, math.radians(settings.blade_rotation)).whole()
    frame = plan_frame(scene, order, camera, lens, settings, rule, math.sqrt(cell.share))  # as the GL path plans it
    per_splat = replace(settings, dof="splat")
    if not frame.layers:
        return None
    plan, guard = frame.layers, frame.guard
    guarded = camera.guarded(guard)
    # the huge-CoC layers are blurred per splat by the cell's share of the aperture, as the GL path
    # draws them (a refinement pass's cell sees that share of the lens)
    lensed = Lens(lens.focus, lens.aperture * math.sqrt(cell.share))
    layers = []
    for layer, (x0, y0, x1, y1) in zip(plan, frame.windows):
        sub = scene.subset(order[layer.first:layer.end])
        blend, sums, _ = _blend(sub, guarded, lensed if layer.lensed else Lens(lens.focus, 0.0), per_splat, tile)
        outside = np.ones(blend.shape[:2], bool)
        outside[max(y0, 0):max(y1, 0), max(x0, 0):max(x1, 0)] = False
        blend[outside] = 0.0
        sums[outside] = 0.0
        layers.append((blend, sums))
    encoded = scene.colour_space == "srgb" and not settings.blend_linear
    return _SlicedLayers((layers, plan, lens, rule, cell, guard, frame.edges), order, encoded)
