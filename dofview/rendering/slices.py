"""Depth-sliced depth of field (layered DoF), the backend-independent math in plain numpy.

The thin lens blurs the *coverage* of a surface, blur(1 − Π(1 − αᵢ)); per-splat enlargement blurs
each splat first, 1 − Π(1 − blur(αᵢ)), which saturates. Here the sorted splats are cut into
contiguous depth ranges (slices) by their signed circle of confusion c = ½·A·(1/z − 1/d_f) px
(positive in front of the focus plane); each slice is blended as the pinhole blends it into its
own premultiplied RGBA image, blurred with the aperture disk of its CoC, and the blurred slices are
composited front to back in the space the scene blends in (display-encoded for sRGB scenes: the
renderer's 2.2 power, tonemap.encode), so that at A = 0 the result is the pinhole render.

Seams: with disjoint slices a surface that crosses many of them (a floor) is blurred by a radius
that steps at each slice edge, and the "over" of two blurred, complementary parts of it lets
the background through (a(1 − b) of coverage lost at each cut). Neighbour sharing
(:func:`share_weights`) makes the radius follow each splat's CoC: the layers are the depth
ranges between consecutive slice centres, and each pixel's content is split between the two
centres' blurs by the blended share τ; the "hybrid" composite fills what "over" loses at the cuts
from the "visible" sum. Neither changes a layer's blend, so unblurred layers are still exactly
the pinhole. (Splitting a splat's *opacity* between two layers instead cannot be exact: the
two halves end up on either side of their neighbours in the blend order, and "over" of different
colours does not commute.)

Splats whose CoC is beyond ``SliceRule.huge`` (near-camera Gaussians indoors, whose blur is
hundreds of pixels) are not sliced: they are drawn by the per-splat method into a front layer
(c > huge) or a back layer (c < −huge), where energy normalisation makes them nearly vanish, as
physically they nearly do.

This is the CPU twin the GL path is tested against (DESIGN.md "Depth-sliced compositing").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dofview.errors import DofviewError
from dofview.lens import Lens
from dofview.tonemap import decode, encode

GUARDS: tuple[str, ...] = ("replicate", "zero")


@dataclass(frozen=True)
class SliceRule:
    """How splats are cut into slices by signed CoC c (pixels).

    Attributes:
        width: width of the slice around the focus plane, px of CoC (it spans [−width/2, width/2]).
        growth: each slice farther from focus is this factor wider than the one before (≥ 1):
            uniform in 1/z near focus, a relative step where the blur is large.
        huge: |c| (px) from which splats leave the slices for the per-splat front/back layers;
            inf keeps every splat in a slice.
    """

    width: float = 1.0
    growth: float = 1.15
    huge: float = 80.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.width) and self.width > 0):
            raise DofviewError(f"slice width must be a finite number of pixels > 0, got {self.width}")
        if not (math.isfinite(self.growth) and self.growth >= 1.0):
            raise DofviewError(f"slice growth must be a finite factor ≥ 1, got {self.growth}")
        if not self.huge > self.width / 2:
            raise DofviewError(f"huge-CoC threshold must exceed half the slice width, got {self.huge}")


def signed_coc(depth: np.ndarray, lens: Lens) -> np.ndarray:
    """(N,) float64 signed CoC c = ½·A·(1/z − 1/d_f) px of camera depths ``depth`` (N,) scene
    units, z > 0: positive in front of the focus plane, so larger c is nearer the camera."""
    return 0.5 * lens.aperture * (1.0 / np.asarray(depth, np.float64) - lens.inv_focus)


def slice_edges(c_min: float, c_max: float, rule: SliceRule) -> np.ndarray:
    """(K + 1,) float64 slice edges in signed CoC px, descending (front to back), covering
    [max(c_min, −huge), min(c_max, huge)]: the focus slice [−w/2, w/2], then slices of width
    w·g, w·g², … outwards on either side. Slice i spans edges[i] ≥ c > edges[i + 1]."""
    lo, hi = max(c_min, -rule.huge), min(c_max, rule.huge)

    def side(limit: float) -> list[float]:
        out, e, w = [], rule.width / 2, rule.width
        while e < limit:
            w *= rule.growth
            e = min(e + w, rule.huge)
            out.append(e)
        return out

    half = rule.width / 2
    front = side(hi)[::-1]
    back = [-e for e in side(-lo)]
    return np.array(front + [half, -half] + back, np.float64)


@dataclass
class Slicing:
    """Splats assigned to slices (see :func:`assign_slices`).

    Attributes:
        edges: (K + 1,) descending signed-CoC edges, px.
        index: (N,) int64 slice of each splat, 0 = frontmost; −1: the per-splat front layer
            (c > huge), K: the per-splat back layer (c < −huge).
        radius: (K,) float64 blur radius of each slice, px: |c| at the slice's middle.
    """

    edges: np.ndarray
    index: np.ndarray
    radius: np.ndarray

    @property
    def count(self) -> int:
        return len(self.edges) - 1


def assign_slices(c: np.ndarray, rule: SliceRule) -> Slicing:
    """Slice each splat of signed CoC ``c`` (N,) px by ``rule``. Slices are contiguous ranges of
    the depth order, so each is blended exactly as the pinhole blends that range."""
    c = np.asarray(c, np.float64)
    if c.size == 0:
        edges = np.array([rule.width / 2, -rule.width / 2])
        return Slicing(edges, np.zeros(0, np.int64), np.zeros(1))
    edges = slice_edges(float(c.min()), float(c.max()), rule)
    # descending edges: count the edges strictly above c (np.searchsorted wants ascending)
    index = len(edges) - np.searchsorted(edges[::-1], c, side="left") - 1
    index = np.where(c > rule.huge, -1, np.where(c < -rule.huge, len(edges) - 1, np.clip(index, 0, len(edges) - 2)))
    return Slicing(edges, index.astype(np.int64), np.abs(0.5 * (edges[:-1] + edges[1:])))


def share_weights(c: np.ndarray, centres: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Neighbour sharing: each splat of signed CoC ``c`` (N,) px lies between two consecutive slice
    centres ``centres`` (K,) descending px. Returns ``interval`` (N,) int64, 0…K: 0 in front of the
    first centre, j between centres j − 1 and j, K behind the last; and ``t`` (N,) float64 ∈ [0, 1],
    the share of the farther centre, linear in c (0 at the nearer centre, 1 at the farther; the end
    intervals belong wholly to their one centre). Intervals are contiguous in depth, so each is
    blended as the pinhole blends it."""
    c = np.asarray(c, np.float64)
    m = np.asarray(centres, np.float64)
    interval = len(m) - np.searchsorted(m[::-1], c, side="right")
    j = np.clip(interval, 1, max(len(m) - 1, 1))
    if len(m) < 2:
        return interval.astype(np.int64), np.zeros_like(c)
    t = np.clip((m[j - 1] - c) / (m[j - 1] - m[j]), 0.0, 1.0)
    t = np.where(interval == 0, 0.0, np.where(interval == len(m), 1.0, t))
    return interval.astype(np.int64), t


# ---- the aperture kernel and the blur --------------------------------------------------------------
def aperture_kernel(radius: float, blades: int = 0, rotation: float = 0.0) -> np.ndarray:
    """(2n + 1, 2n + 1) float64 kernel of the aperture, sum 1, n = ceil(radius + ½): a disk of
    ``radius`` px (``blades`` = 0) or a regular polygon with ``blades`` ≥ 3 corners on that circle,
    the first at ``rotation`` radians from +x. Anti-aliased: each pixel's weight is its coverage
    estimated from the signed distance of its centre to the edge, clip(½ − distance, 0, 1), so the
    kernel changes continuously with the radius; radius < ½ is the identity."""
    if blades and blades < 3:
        raise DofviewError(f"an aperture needs 0 (a disk) or ≥ 3 blades, got {blades}")
    if not (radius >= 0 and math.isfinite(radius)):
        raise DofviewError(f"blur radius must be a finite number of pixels ≥ 0, got {radius}")
    n = int(math.ceil(radius + 0.5))
    y, x = np.mgrid[-n:n + 1, -n:n + 1].astype(np.float64)
    if blades:
        normals = rotation + (np.arange(blades) + 0.5) * (2 * math.pi / blades)
        dist = np.max(x[..., None] * np.cos(normals) + y[..., None] * np.sin(normals), axis=-1)
        dist -= radius * math.cos(math.pi / blades)
    else:
        dist = np.hypot(x, y) - radius
    k = np.clip(0.5 - dist, 0.0, 1.0)
    if k.sum() == 0:  # a polygon too small to cover any pixel centre: the identity
        k[n, n] = 1.0
    return k / k.sum()


def _convolve(img: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """'valid' 2D convolution of the first two axes of ``img`` (H, W, C) with ``kernel`` (FFT)."""
    kh, kw = kernel.shape
    h, w = img.shape[:2]
    fh, fw = h + kh - 1, w + kw - 1
    spec = np.fft.rfft2(img, (fh, fw), axes=(0, 1)) * np.fft.rfft2(kernel, (fh, fw))[..., None]
    full = np.fft.irfft2(spec, (fh, fw), axes=(0, 1))
    return full[kh - 1:h, kw - 1:w]


def blur_slice(rgba: np.ndarray, radius: float, guard: str = "replicate", blades: int = 0,
               rotation: float = 0.0, scale: int = 1) -> np.ndarray:
    """(H, W, 4) premultiplied RGBA of one slice blurred by the aperture of ``radius`` px.

    ``guard``: the scene a blur of radius r needs beyond the frame, r px on each side:
    "replicate" extends the slice by its edge pixels (a wall crossing the border keeps its
    coverage there), "zero" by nothing (the border loses coverage). ``scale`` > 1 blurs at 1/scale
    resolution (box-averaged down, bilinear up), as a GPU does for large radii.
    """
    if guard not in GUARDS:
        raise DofviewError(f"guard band must be one of {', '.join(GUARDS)}, got {guard!r}")
    img = np.asarray(rgba, np.float64)
    if radius < 0.5:
        return img.copy()
    h, w = img.shape[:2]
    if scale > 1:
        ph, pw = -h % scale, -w % scale
        small = np.pad(img, ((0, ph), (0, pw), (0, 0)), mode="edge")
        small = small.reshape((h + ph) // scale, scale, (w + pw) // scale, scale, 4).mean(axis=(1, 3))
        out = blur_slice(small, radius / scale, guard, blades, rotation)
        return _upsample(out, scale, h, w)
    kernel = aperture_kernel(radius, blades, rotation)
    n = kernel.shape[0] // 2
    mode = "edge" if guard == "replicate" else "constant"
    return _convolve(np.pad(img, ((n, n), (n, n), (0, 0)), mode=mode), kernel)


def _upsample(img: np.ndarray, scale: int, h: int, w: int) -> np.ndarray:
    """Bilinear upsampling by ``scale`` of (h', w', C), pixel centres aligned, cropped to (h, w)."""
    def axis_weights(n_out: int, n_in: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        pos = np.clip((np.arange(n_out) + 0.5) / scale - 0.5, 0.0, n_in - 1)
        i0 = np.floor(pos).astype(np.int64)
        i1 = np.minimum(i0 + 1, n_in - 1)
        return i0, i1, pos - i0

    y0, y1, fy = axis_weights(h, img.shape[0])
    x0, x1, fx = axis_weights(w, img.shape[1])
    rows = img[y0] * (1 - fy)[:, None, None] + img[y1] * fy[:, None, None]
    return rows[:, x0] * (1 - fx)[None, :, None] + rows[:, x1] * fx[None, :, None]


# ---- compositing ------------------------------------------------------------------------------------
def to_blend_space(rgba: np.ndarray, encoded: bool) -> np.ndarray:
    """A Frame's (H, W, 4) linear premultiplied RGBA → the space the renderer blended it in: for an
    encoded (sRGB) scene the Frame holds decode(C) of the encoded premultiplied blend C, so C =
    encode(rgb); a linear scene blends in linear light."""
    out = np.array(rgba, np.float64)
    if encoded:
        out[..., :3] = encode(out[..., :3])
    return out


def from_blend_space(rgba: np.ndarray, encoded: bool) -> np.ndarray:
    """The inverse of :func:`to_blend_space`: (H, W, 4) float32 linear premultiplied RGBA."""
    out = np.array(rgba, np.float64)
    if encoded:
        out[..., :3] = decode(out[..., :3])
    return out.astype(np.float32)


def composite(layers: list[np.ndarray]) -> np.ndarray:
    """Front-to-back "over" of premultiplied (H, W, 4) layers in one space, nearest first: each
    layer adds its colour and coverage under the transmittance of those in front of it."""
    out = np.zeros_like(np.asarray(layers[0], np.float64))
    for layer in layers:
        out += (1.0 - out[..., 3:4]) * layer
    return out


COMPOSITES: tuple[str, ...] = ("over", "visible", "hybrid")


def sliced_image(layers: list[np.ndarray], radii: list[float], encoded: bool, guard: str = "replicate",
                 blades: int = 0, rotation: float = 0.0, blur_linear: bool = False,
                 max_full_radius: float = math.inf, mode: str = "over", centres: list[float] | None = None,
                 window: float = 0.0, splits: list[tuple[np.ndarray, float] | None] | None = None) -> np.ndarray:
    """The depth of field image from unblurred slice images: (H, W, 4) float32 linear premultiplied.

    ``layers``: the slices' Frame RGBA (linear, as the renderer reads them back), front to back;
    ``radii``: each one's blur radius px (0 for a layer drawn already blurred, like the per-splat
    huge-CoC layers). Blur and composite happen in the blend space (``blur_linear``: blur the linear
    light instead, a variant for measurement). Radii above ``max_full_radius`` blur at the reduced
    resolution that brings them below it.

    ``mode``: "over" composites the blurred slices front to back (hidden surfaces show where a
    blurred edge thins, but a surface cut by slice boundaries loses coverage at each cut);
    "visible" sums the blurred *visible* part of each slice, T·C with T the pinhole transmittance
    in front of it (a surface crossing slices stays whole; nothing hidden is revealed, and a blurred
    foreground spilling over a sharp background adds coverage beyond 1); "hybrid" is "over" with
    its coverage deficit against "visible" (capped at 1) filled by the visible composite's colour,
    so the seams close while what "over" reveals stays. All three are the pinhole at A = 0.

    ``window`` > 0 (mode "over", needs ``centres``: each layer's signed CoC px, ±inf for the
    per-splat layers) makes the cut between slices seamless: a layer is occluded by the layers
    in front of it whose centre lies within ``window`` px of CoC of its own *before* it is
    blurred (their pinhole transmittance, so the complementary parts of one surface cut by the
    slices add up instead of thinning each other), and by the farther ones after (the "over" that
    reveals what a blurred foreground hid). The parallax between two depths is their CoC
    difference, so what the pre-blur occlusion keeps hidden is at most ``window`` px wide. The two
    transmittances multiply to the pinhole's, so unblurred layers still composite to it exactly.

    ``splits``: per layer None, or (τ, r₂) for a layer shared between two slice centres (see
    :func:`share_weights`): τ (H, W) is the fraction of each pixel's content that belongs to the
    farther centre, blurred by r₂ px, the rest by the layer's radius. The two parts add up to the
    layer, so this too is the pinhole at zero blur, and a splat's blur follows its CoC
    continuously instead of stepping at slice edges.
    """
    if mode not in COMPOSITES:
        raise DofviewError(f"slice composite must be one of {', '.join(COMPOSITES)}, got {mode!r}")

    def blur(img: np.ndarray, r: float) -> np.ndarray:
        scale = 1 if r <= max_full_radius else 1 << math.ceil(math.log2(r / max_full_radius))
        if blur_linear:
            return to_blend_space(blur_slice(from_blend_space(img, encoded), r, guard, blades, rotation, scale),
                                  encoded)
        return blur_slice(img, r, guard, blades, rotation, scale)

    def blur_layer(img: np.ndarray, i: int) -> np.ndarray:
        split = splits[i] if splits is not None else None
        if split is None:
            return blur(img, radii[i])
        tau = np.asarray(split[0], np.float64)[..., None]
        return blur(img * (1.0 - tau), radii[i]) + blur(img * tau, split[1])

    if window > 0:
        if mode != "over" or centres is None or len(centres) != len(layers):
            raise DofviewError("a seam window needs mode 'over' and one CoC centre per layer")
        return from_blend_space(_windowed_over([to_blend_space(l, encoded) for l in layers], centres, window,
                                               blur_layer), encoded)
    over, visible = [], None
    trans = None
    for i, rgba in enumerate(layers):
        img = to_blend_space(rgba, encoded)
        if mode != "visible":
            over.append(blur_layer(img, i))
        if mode != "over":
            trans = np.ones(img.shape[:2] + (1,)) if trans is None else trans
            part = blur_layer(trans * img, i)
            visible = part if visible is None else visible + part
            trans = trans * (1.0 - img[..., 3:4])
    if mode == "over":
        out = composite(over)
    elif mode == "visible":
        out = visible
    else:
        out = composite(over)
        vis_a = visible[..., 3:4]
        deficit = np.clip(np.minimum(vis_a, 1.0) - out[..., 3:4], 0.0, None)
        out = out + visible * np.where(vis_a > 0, deficit / np.maximum(vis_a, 1e-12), 0.0)
    return from_blend_space(out, encoded)


def _windowed_over(imgs: list[np.ndarray], centres: list[float], window: float, blur) -> np.ndarray:
    """The "over" composite of blend-space layers ``imgs`` (front to back) in which the layers
    within ``window`` px of CoC in front of each one occlude it before its blur (see :func:`sliced_image`); ``blur(img, i)`` blurs layer i."""
    far = [np.ones(imgs[0].shape[:2] + (1,))]  # far[k]: transmittance of layers 0…k−1, each blurred
    for k in range(len(imgs) - 1):
        far.append(far[-1] * (1.0 - blur(imgs[k][..., 3:4].repeat(4, axis=-1), k)[..., 3:4]))
    out = np.zeros_like(imgs[0])
    for i, img in enumerate(imgs):
        # the per-splat layers (centre ±inf) only ever occlude after the blur
        reach = window if math.isfinite(centres[i]) else -math.inf
        start = i
        while start > 0 and centres[start - 1] - centres[i] <= reach:
            start -= 1
        near = np.ones_like(far[0])
        for k in range(start, i):
            near *= 1.0 - imgs[k][..., 3:4]
        out += far[start] * blur(near * img, i)
    return out
