"""Depth-sliced depth of field (layered DoF): the plan and the image math, in plain numpy.

The thin lens blurs the *coverage* of a surface, blur(1 − Π(1 − αᵢ)); per-splat enlargement blurs
each splat first, 1 − Π(1 − blur(αᵢ)), which saturates. Here the depth-sorted splats are cut into
contiguous ranges (layers) by their signed circle of confusion c = ½·A·(1/z − 1/d_f) px (positive
in front of the focus plane, :func:`plan_layers`); each layer is blended as the pinhole blends it
and then blurred, and the blurred layers are composited front to back in the space the scene
blends in (display-encoded for sRGB scenes: the renderer's 2.2 power), so that at A = 0 the
result is the pinhole render.

The blur scatters every pixel of a layer over the aperture at *its own* CoC: the pixel's content
has the α-weighted mean inverse depth of the splats blended there (the depth target's Σw/z over
Σw), so its blur is exact, whatever the layer's width, and a surface crossing layers (a floor)
is blurred by a radius that follows its depth without steps. As a gather (:func:`scatter`):
out(p) = Σ_d L(p − d)·w(d, c(p − d)) / N(c(p − d)), with w the anti-aliased aperture (a disk or
a polygon, or a cell of a partition of it: :class:`LensCell`) scaled by the source's signed CoC c
(turned half a turn in front of focus, as a lens shows it) and N(c) = Σ_d w(d, c), so every
pixel's light is kept exactly; at |c| < ½ it is the identity. Samples beyond the frame repeat its
edge (a guard band: a wall crossing the border keeps its coverage there).

Layers whose smallest radius exceeds :attr:`SliceRule.limit` blur at 1/s resolution (s = 2, 4, …):
the layer is averaged 2 × 2 down to s × s blocks (:func:`reduce2`; pixel radius from the block's
mean inverse depth, shrunk so that the down- and upsampling's own spread is not added twice:
r′² = r² − 4β(s² − 1)), gathered there, and upsampled bilinearly. Consecutive layers of one
resolution (a *run*) are composited at that resolution and upsampled once.

Seams: where a surface is cut between two layers, their blurred parts are complementary, and
"over" of the two loses a(1 − b) of coverage along the cut. The sum of the blurred *visible* parts
(each layer's coverage under the pinhole transmittance in front of it) keeps a surface whole but
cannot show what a blurred foreground edge hid; the resolve (:func:`resolve`) scales the "over"
composite up to that sum's coverage (capped at 1) where it falls short, so cuts close and hidden
surfaces still show.

Near-camera Gaussians indoors, blurred by hundreds of pixels, are sliced like the rest (at levels
down to a few texels, their light kept): a wall a hand's breadth from the lens stays an opaque blur.
A finite :attr:`SliceRule.huge` instead draws the splats beyond it by the per-splat method as a
front and a back layer, where energy normalisation makes them nearly vanish (the benchmark
compares the two: docs/BENCHMARKS.md, "Sliced depth of field", indoors).

This module is the CPU twin of the GL path (rendering/sliced.py), pass for pass: images are in
GL orientation there (rows from the bottom), so :func:`sliced_image` flips its inputs, and blocks
of a reduced level align at the bottom-left corner as the GL targets do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from dofview.errors import DofviewError
from dofview.lens import Lens
from dofview.tonemap import decode, encode


@dataclass(frozen=True)
class SliceRule:
    """How splats are cut into layers by signed CoC c (pixels), and how far each is blurred at full
    resolution.

    Attributes:
        width: width of the layer around the focus plane, px of CoC (it spans [−width/2, width/2]).
        growth: each layer farther from focus is this factor wider than the one before (≥ 1):
            uniform in 1/z near focus, a relative step where the blur is large.
        huge: |c| (px) from which splats leave the layers for the per-splat front/back layers;
            inf (the default) keeps every splat in a layer.
        limit: largest blur radius px gathered at full resolution; a layer blurred further
            blurs at the 1/2ᵏ resolution that brings its smallest radius to ≤ limit.
        spread: β, the variance (px², per axis, per s² − 1) that the box average and the bilinear
            upsampling of a 1/s level add; each radius there is shrunk by it: r′² = r² − 4β(s² − 1).
    """

    width: float = 1.0
    growth: float = 1.15
    huge: float = math.inf
    limit: float = 3.0
    spread: float = 1.0 / 6.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.width) and self.width > 0):
            raise DofviewError(f"slice width must be a finite number of pixels > 0, got {self.width}")
        if not (math.isfinite(self.growth) and self.growth >= 1.0):
            raise DofviewError(f"slice growth must be a finite factor ≥ 1, got {self.growth}")
        if not self.huge > self.width / 2:
            raise DofviewError(f"huge-CoC threshold must exceed half the slice width, got {self.huge}")
        if not (math.isfinite(self.limit) and self.limit >= 1.0):
            raise DofviewError(f"full-resolution blur limit must be a finite radius ≥ 1 px, got {self.limit}")
        if not (math.isfinite(self.spread) and self.spread >= 0.0):
            raise DofviewError(f"level spread must be a finite variance ≥ 0, got {self.spread}")


    def scale(self, radius: float) -> int:
        """The resolution reduction (1, 2, 4, …) that brings a blur of ``radius`` px to ≤ :attr:`limit`."""
        ratio = radius / self.limit * (1.0 - 1e-6)  # a radius a rounding above a power of two stays below it
        return 1 if ratio <= 1.0 else 1 << math.ceil(math.log2(ratio))


SLICE_RULE = SliceRule()
"""The rule of the sliced mode (the GL path and its CPU twin alike); chosen by measurement
(docs/BENCHMARKS.md, "Sliced depth of field")."""
BLADED_LIMIT = 6.0
"""Full-resolution blur limit px with a bladed aperture: a polygon gathered at ≤ 3 px and upsampled
comes out a round blob; at 6 px its corners show."""


def rule_for(blades: int) -> SliceRule:
    """The sliced mode's rule for an aperture of ``blades`` (0: the disk)."""
    return replace(SLICE_RULE, limit=max(SLICE_RULE.limit, BLADED_LIMIT)) if blades else SLICE_RULE


def signed_coc(depth: np.ndarray, lens: Lens) -> np.ndarray:
    """(N,) float64 signed CoC c = ½·A·(1/z − 1/d_f) px of camera depths ``depth`` (N,) scene
    units, z > 0: positive in front of the focus plane, so larger c is nearer the camera."""
    return 0.5 * lens.aperture * (1.0 / np.asarray(depth, np.float64) - lens.inv_focus)


def slice_edges(c_min: float, c_max: float, rule: SliceRule) -> np.ndarray:
    """(K + 1,) float64 layer edges in signed CoC px, descending (front to back), covering
    [max(c_min, −huge), min(c_max, huge)]: the focus layer [−w/2, w/2], then layers of width
    w·g, w·g², … outwards on either side. Layer i spans edges[i] ≥ c > edges[i + 1]."""
    lo, hi = max(c_min, -rule.huge), min(c_max, rule.huge)

    def side(limit: float) -> list[float]:
        out, e, w = [], rule.width / 2, rule.width
        while e < limit:
            w *= rule.growth
            e = min(e + w, rule.huge)
            out.append(e)
        return out

    half = rule.width / 2
    return np.array(side(hi)[::-1] + [half, -half] + [-e for e in side(-lo)], np.float64)


@dataclass(frozen=True)
class Layer:
    """One range [first, end) of the front-to-back draw order.

    Attributes:
        first, end: the range, in draw order.
        lensed: a huge-CoC layer, drawn with the lens by the per-splat method and not blurred.
        radius: the largest |CoC| px of its splats (0 for a lensed layer).
        scale: the resolution reduction of its blur (1 full resolution, 2, 4, …): the one that
            brings its smallest |CoC| to ≤ SliceRule.limit (and its largest to ≤ limit + 2).
    """

    first: int
    end: int
    lensed: bool
    radius: float
    scale: int


def plan_layers(depth: np.ndarray, lens: Lens, near: float, rule: SliceRule = SliceRule(),
                size: float = 1.0) -> list[Layer]:
    """The non-empty layers, front to back, of Gaussians at camera depths ``depth`` (N,) scene
    units in draw order, nearest first; those at z ≤ ``near`` (culled) join the layer before them.
    ``size``: the kernel's scale against the whole aperture's (√share of a lens cell: its
    equal-area disk), which sets each layer's resolution: a small cell's shape needs a finer level.
    An order sorted for an earlier view (the viewer's background sort) is nearly sorted: each
    Gaussian takes the farthest layer of those before it, so the ranges stay contiguous."""
    depth = np.asarray(depth, np.float64)
    live = depth > near
    if not live.any():
        return []
    c = signed_coc(depth[live], lens)
    edges = slice_edges(float(c.min()), float(c.max()), rule)
    k = len(edges) - 1
    # descending edges: count the edges strictly above c (np.searchsorted wants ascending)
    index = np.clip(k - np.searchsorted(edges[::-1], c, side="left"), 0, k - 1)
    index = np.where(c > rule.huge, -1, np.where(c < -rule.huge, k, index))
    key = np.full(len(depth), -2, np.int64)  # -2: culled; -1 the front layer, 0…k−1 the slices, k the back layer
    key[live] = index
    key = np.maximum.accumulate(key)
    bounds = np.searchsorted(key, np.arange(-1, k + 2), side="left")
    coc = np.full(len(depth), np.nan)  # culled: in no layer's range of blur
    coc[live] = np.abs(c)
    layers = []
    for v in range(-1, k + 1):
        first, end = int(bounds[v + 1]), int(bounds[v + 2])
        if end <= first:
            continue
        if v in (-1, k):
            layers.append(Layer(first, end, True, 0.0, 1))
            continue
        part = coc[first:end]
        lo, hi = float(np.nanmin(part)), float(np.nanmax(part))
        # the level by the layer's *smallest* blur: where a surface runs from one layer into the
        # next, both blur it alike only if the farther layer's level still resolves its nearest
        # pixels (by the largest, a floor shows a band at every change of level); but no finer
        # than brings the largest to limit + 2 (an earlier view's order mixes blurs in a layer)
        scale = max(rule.scale(lo * size), replace(rule, limit=rule.limit + 2.0).scale(hi * size))
        layers.append(Layer(first, end, False, hi, scale))
    return layers


# ---- the aperture ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Aperture:
    """The aperture's shape: a disk (``blades`` = 0) or a regular polygon with ``blades`` ≥ 3
    corners on the circle of the blur radius, the first ``rotation`` radians from +x (image right,
    rows downwards)."""

    blades: int = 0
    rotation: float = 0.0

    def __post_init__(self) -> None:
        if self.blades and self.blades < 3:
            raise DofviewError(f"an aperture needs 0 (a disk) or ≥ 3 blades, got {self.blades}")

    def planes(self) -> np.ndarray:
        """(B, 3) float64 the polygon's edges as half-planes u·n ≤ h (n a unit normal, h = cos(π/B),
        lens radii, image orientation); (0, 3) for the disk."""
        if not self.blades:
            return np.zeros((0, 3))
        a = self.rotation + (np.arange(self.blades) + 0.5) * (2 * math.pi / self.blades)
        return np.stack([np.cos(a), np.sin(a), np.full(self.blades, math.cos(math.pi / self.blades))], 1)

    def inside(self, u: np.ndarray) -> np.ndarray:
        """(…) bool: the points ``u`` (…, 2) lens radii, image orientation, lie on the aperture."""
        if not self.blades:
            return np.hypot(u[..., 0], u[..., 1]) <= 1.0
        pl = self.planes()
        return np.all(u[..., None, 0] * pl[:, 0] + u[..., None, 1] * pl[:, 1] <= pl[:, 2], axis=-1)

    def whole(self) -> "LensCell":
        """The whole aperture as one cell, seen from its centre: the single pass's kernel."""
        return LensCell(self.planes(), not self.blades, np.zeros(2), 1.0, 1.0)


@dataclass(frozen=True, eq=False)
class LensCell:
    """A part of the lens (lens radii; camera axes: x right, y down, as the image): the unit disk
    (``disk``) cut by the half-planes u·n ≤ h of ``planes`` (P, 3) (an aperture polygon's edges,
    the bisectors to the neighbouring cells of a partition), seen from ``point`` (2,) inside it,
    ``share`` of the lens's area, no point of it farther than ``reach`` from ``point``.

    Its kernel: seen from lens point u, a point of signed CoC c px (positive in front of focus)
    moves by −c·u on the image (Camera.lens_shifted), so a pass from ``point`` spreads each source
    over the offsets d = −c·(u − point), u in the cell: the cell's shape about ``point``, scaled by
    |c|, turned half a turn in front of focus. :meth:`weights` is that shape anti-aliased: w =
    clip(½ − sd, 0, 1) with sd the signed distance in px (the largest of the disk's and the planes').
    The whole aperture (Aperture.whole) is the single pass's kernel; the cells of a partition of the
    lens are progressive refinement's, whose passes add up to the whole lens exactly."""

    planes: np.ndarray
    disk: bool
    point: np.ndarray
    share: float
    reach: float

    def gl(self) -> tuple[np.ndarray, np.ndarray]:
        """``point`` (2,) and ``planes`` (P, 3) float32 in GL orientation (y upwards), as the shaders use them."""
        flip = np.array([1.0, -1.0])
        pl = np.array(self.planes, np.float64).reshape(-1, 3)
        return ((self.point * flip).astype(np.float32),
                np.concatenate([pl[:, :2] * flip, pl[:, 2:]], 1).astype(np.float32))

    def weights(self, d: np.ndarray, rho: np.ndarray) -> np.ndarray:
        """(T, …) float32 w(d, ρ) of offsets ``d`` (T, 2) px, GL orientation, for sources of
        signed CoC ``rho`` (…) px (slice_kernel.glsl is the twin); ρ = 0 is the identity."""
        point, planes = self.gl()
        rho = np.asarray(rho, np.float32)
        a = np.abs(rho)[None]
        sgn = np.where(rho < 0, np.float32(-1.0), np.float32(1.0))[None]
        ex = (slice(None),) + (None,) * rho.ndim
        vx = a * point[0] - sgn * np.asarray(d[:, 0], np.float32)[ex]  # |ρ|·u in px, u = point − d/ρ
        vy = a * point[1] - sgn * np.asarray(d[:, 1], np.float32)[ex]
        sd = np.sqrt(vx * vx + vy * vy) - a if self.disk else np.full(np.broadcast(vx, a).shape, -np.inf, np.float32)
        for nx, ny, h in planes:
            sd = np.maximum(sd, vx * nx + vy * ny - a * h)
        return np.clip(np.float32(0.5) - sd, 0.0, 1.0).astype(np.float32)

    def taps(self, radius: float) -> np.ndarray:
        """(T, 2) float32 the offsets (GL orientation) where the kernel of a source of |ρ| ≤
        ``radius`` px has weight, nearest first (the kernels of smaller |ρ| lie inside)."""
        n = int(math.ceil(self.reach * max(radius, 0.0) + 1.5))
        dy, dx = np.mgrid[-n:n + 1, -n:n + 1]
        d = np.stack([dx.ravel(), dy.ravel()], 1).astype(np.float32)
        reach = np.max(self.weights(d, np.array([radius, -radius], np.float32)), axis=1) > 0
        d = d[reach | np.all(d == 0, axis=1)]
        return d[np.lexsort((d[:, 0], d[:, 1], np.hypot(d[:, 0], d[:, 1])))]


def aperture_kernel(radius: float, blades: int = 0, rotation: float = 0.0) -> np.ndarray:
    """(2n + 1, 2n + 1) float64 kernel of the aperture, sum 1, image orientation (rows downwards),
    for a source behind the focus plane (in front it is turned half a turn): the weights
    w(d, radius)/N that :func:`scatter` spreads one pixel of that blur radius over. radius < ½ is
    the identity."""
    if not (radius >= 0 and math.isfinite(radius)):
        raise DofviewError(f"blur radius must be a finite number of pixels ≥ 0, got {radius}")
    cell = Aperture(blades, rotation).whole()
    taps = cell.taps(radius)
    w = cell.weights(taps, np.float32(-radius)).astype(np.float64)
    n = int(np.abs(taps).max())
    k = np.zeros((2 * n + 1, 2 * n + 1))
    k[n - taps[:, 1].astype(int), n + taps[:, 0].astype(int)] = w  # GL dy upwards → rows downwards
    return k / k.sum()


# ---- the passes (GL orientation: rows from the bottom) ------------------------------------------
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


def prepare(colour: np.ndarray, depth_sums: np.ndarray, acc_depth: np.ndarray, lens: Lens, layer: Layer,
            rule: SliceRule, cell: LensCell, taps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One layer made ready for its gather at its level 1/s (slice_visible.comp, slice_reduce.frag,
    slice_prepare.frag).

    ``colour`` (H, W, 4) its blend-space premultiplied RGBA, ``depth_sums`` (H, W, 4) its
    (Σw·z, Σw/z, 0, Σw); ``acc_depth`` (H, W, 4) float64 the depth sums of the layers in front,
    to which this layer's are added under their transmittance T (in place): the pinhole's depth.
    The layer's visible coverage T·α rides along with its depth sums through the 2 × 2 averages
    (:func:`reduce2`) down to the level. Returns ``a`` (h, w, 4) the level's colour over N(ρ) =
    Σ_taps w(d, ρ) of each texel's signed CoC ρ (level px, shrunk: see the module docstring) and
    ``b`` (h, w, 2) (ρ, visible coverage / N(ρ))."""
    trans = 1.0 - acc_depth[..., 3]
    acc_depth += trans[..., None] * depth_sums
    col = np.asarray(colour, np.float64)
    dep = np.array(depth_sums, np.float64)
    dep[..., 2] = trans * col[..., 3]
    s = layer.scale
    for _ in range(s.bit_length() - 1):
        col, dep = reduce2(col), reduce2(dep)
    if layer.lensed:
        rho = np.zeros(col.shape[:2])
    else:
        w = dep[..., 3]
        c = np.where(w > 0, 0.5 * lens.aperture * (dep[..., 1] / np.where(w > 0, w, 1.0) - lens.inv_focus), 0.0)
        r = np.minimum(np.sqrt(np.maximum(c * c - 4.0 * rule.spread * (s * s - 1), 0.0)) / s, layer.radius / s)
        rho = np.where(w > 0, np.copysign(r, c), 0.0)
    rho = rho.astype(np.float32)
    norm = cell.weights(taps, rho).sum(axis=0, dtype=np.float64)
    return col / norm[..., None], np.stack([rho, dep[..., 2] / norm], -1)


def reduce2(x: np.ndarray) -> np.ndarray:
    """(⌈h/2⌉, ⌈w/2⌉, …) averages of the 2 × 2 blocks of ``x`` (h, w, …) from the origin, each
    over the texels of its block inside ``x`` (slice_reduce.frag)."""
    h, w = x.shape[:2]
    ph, pw = h % 2, w % 2
    pad = ((0, ph), (0, pw)) + ((0, 0),) * (x.ndim - 2)
    sums = np.pad(np.asarray(x, np.float64), pad).reshape((h + ph) // 2, 2, (w + pw) // 2, 2, *x.shape[2:])
    count = np.pad(np.ones((h, w)), pad[:2]).reshape((h + ph) // 2, 2, (w + pw) // 2, 2).sum(axis=(1, 3))
    return sums.sum(axis=(1, 3)) / count.reshape(count.shape + (1,) * (x.ndim - 2))


def scatter(a: np.ndarray, b: np.ndarray, cell: LensCell, taps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The gather (slice_gather.frag): every pixel of ``a`` (h, w, 4) spread over the kernel of
    ``cell`` for its own signed CoC b[…, 0] (level px), its visible coverage b[…, 1] alike, read
    with the edge repeated beyond the frame. Returns the blurred colour (h, w, 4) and visible
    coverage (h, w)."""
    h, w = a.shape[:2]
    n = int(np.abs(taps).max()) if len(taps) else 0
    ap = np.pad(a, ((n, n), (n, n), (0, 0)), mode="edge")
    bp = np.pad(b, ((n, n), (n, n), (0, 0)), mode="edge")
    out, vis = np.zeros((h, w, 4)), np.zeros((h, w))
    for d in taps:
        x0, y0 = n - int(d[0]), n - int(d[1])  # the source p − d
        src_b = bp[y0:y0 + h, x0:x0 + w]
        wt = cell.weights(d[None], src_b[..., 0])[0]
        out += wt[..., None] * ap[y0:y0 + h, x0:x0 + w]
        vis += wt * src_b[..., 1]
    return out, vis


def upsample(img: np.ndarray, scale: int, h: int, w: int) -> np.ndarray:
    """Bilinear upsampling by ``scale`` of (h′, w′, …) to (h, w, …), pixel centres aligned, clamped
    at the borders (slice_upsample.frag)."""
    def axis(n_out: int, n_in: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        pos = np.clip((np.arange(n_out) + 0.5) / scale - 0.5, 0.0, n_in - 1)
        i0 = np.floor(pos).astype(np.int64)
        return i0, np.minimum(i0 + 1, n_in - 1), pos - i0

    y0, y1, fy = axis(h, img.shape[0])
    x0, x1, fx = axis(w, img.shape[1])
    ex = (slice(None),) + (None,) * (img.ndim - 1)
    rows = img[y0] * (1 - fy)[ex] + img[y1] * fy[ex]
    ex = (None, slice(None)) + (None,) * (img.ndim - 2)
    return rows[:, x0] * (1 - fx)[ex] + rows[:, x1] * fx[ex]


def resolve(over: np.ndarray, visible: np.ndarray) -> np.ndarray:
    """The image from the "over" composite (H, W, 4) and the sum of blurred visible coverages
    (H, W) (slice_resolve.frag): "over", scaled up to the visible sum where its coverage falls
    short of it, and down to full coverage where it exceeds that (a source's kernel keeps its
    light, but where the blur radius changes across a surface neighbouring kernels overlap)."""
    a = over[..., 3]
    target = np.minimum(np.maximum(a, visible), 1.0)
    return over * np.where(a > 0, target / np.where(a > 0, a, 1.0), 1.0)[..., None]


def sliced_image(layers: list[tuple[np.ndarray, np.ndarray]], plan: list[Layer], lens: Lens,
                 rule: SliceRule = SliceRule(), cell: LensCell | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The depth-of-field image from the layers of ``plan`` as blended, front to back: per layer
    (colour (H, W, 4) premultiplied RGBA *in the blend space*, depth sums (H, W, 4) (Σw·z, Σw/z,
    0, Σw)), image orientation (rows downwards), blurred by the kernel of ``cell`` (default: the
    whole disk). Returns the colour (H, W, 4) float64 in the blend space and the depth sums
    (H, W, 4) float64 of the pinhole (the layers composited unblurred)."""
    cell = cell or Aperture().whole()
    h, w = layers[0][0].shape[:2]
    over, visible = np.zeros((h, w, 4)), np.zeros((h, w))
    acc_depth = np.zeros((h, w, 4))
    run: list[object] = []  # [scale, over, visible] of the run of reduced layers being composited

    def end_run() -> None:
        nonlocal over, visible
        if run:
            s, r_over, r_vis = run
            over += (1.0 - over[..., 3:4]) * upsample(r_over, s, h, w)
            visible += upsample(r_vis, s, h, w)
            run.clear()

    for (colour, depth_sums), layer in zip(layers, plan):
        taps = cell.taps(layer.radius / layer.scale)
        a, b = prepare(np.asarray(colour[::-1], np.float64), np.asarray(depth_sums[::-1], np.float64), acc_depth,
                       lens, layer, rule, cell, taps)
        blurred, vis = scatter(a, b, cell, taps)
        if layer.scale == 1:
            end_run()
            over += (1.0 - over[..., 3:4]) * blurred
            visible += vis
            continue
        if run and run[0] != layer.scale:
            end_run()
        if not run:
            run.extend([layer.scale, np.zeros_like(blurred), np.zeros_like(vis)])
        run[1] += (1.0 - run[1][..., 3:4]) * blurred
        run[2] += vis
    end_run()
    return resolve(over, visible)[::-1], acc_depth[::-1]
