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
pixel's light is kept exactly; at |c| < ½ it is the identity.

The guard band: a layer blurred by c px takes light from up to c px beyond the frame. Where a
layer's Gaussians reach beyond the frame (:func:`screen_boxes`, cut to the widest band), the
layers are blended into an image extended on every side (Camera.guarded: the frustum clamp stays
the frame's, so every footprint is the pinhole's) by what their blurs need (:func:`guard_band`: in
steps doubling from 32 px, at most an eighth of the frame's larger side), each layer within its
own reach of the frame (:func:`layer_windows`). Beyond what was rendered the gather repeats the
edge only on the sides where the layer goes on (:func:`layer_edges`: a wall stays opaque to the
border) and reads nothing elsewhere: repeating a coarse level's edge texel, which averages a
block reaching far into the frame, would spread that block over the whole kernel.

Layers whose smallest radius exceeds :attr:`SliceRule.limit` blur at 1/s resolution (s = 2, 4, …):
the layer is averaged 2 × 2 down to s × s blocks (:func:`reduce2`; pixel radius from the block's
mean inverse depth, shrunk so that the down- and upsampling's own spread is not added twice:
r′² = r² − 4β(s² − 1)), gathered there, and upsampled bilinearly. Consecutive layers of one
resolution (a *run*) are composited at that resolution and upsampled once.

Highlights: a small bright source reduced to a coarse level is gathered as a soft, blocky blob
(a point 40 px out of focus got a 90→10 % edge of 27 px where the lens gives 11). So before a
layer is reduced, each pixel whose brightness stands out of the mean of its neighbourhood at the
level's scale (:func:`highlight_share`: a point, a small cluster, the rim of an HDR source) gives
that share of its light, coverage and depth sums to a *sprite* (:func:`highlights`, at most
SliceRule.sprites of the frame's pixels), drawn at full resolution with the gather's own kernel at
the pixel's own signed CoC, normalised by the kernel's exact sum (:func:`draw_sprites`): the disk
or polygon with the lens's edge, and a lens cell's exact shape, so refinement's cells tile the
lens's disc instead of showing one soft copy each. A layer that may have sprites is composited on
its own (a run of one layer, its sprites added to its upsampled image), so that the layers behind
it are hidden by its sprites' coverage as by its gathered one.

Seams: where a surface is cut between two layers, their blurred parts are complementary, and
"over" of the two loses a(1 − b) of coverage along the cut. The sum of the blurred *visible* parts
(each layer's coverage under the pinhole transmittance in front of it) keeps a surface whole but
cannot show what a blurred foreground edge hid; the resolve (:func:`resolve`) scales the "over"
composite up to that sum's coverage (capped at 1) where it falls short, so cuts close and hidden
surfaces still show.

Geometry at the lens (rooms, corridors: a wall beside the camera, floaters): splats blurred beyond
:attr:`SliceRule.huge` of the frame leave the layers for a front and a back layer drawn by the
per-splat method with the lens, where energy normalisation spreads them thin, as physically they
nearly vanish. Sliced, they fog a room: a surface seen at a grazing angle near the lens is cut into
many layers, and blurring each layer's pinhole image gives every slice of the wall its pinhole
width, while through the lens it is seen nearly edge-on from the lens points that carry its light
to a pixel (a wall 3 cm beside a 7.7 cm aperture, sliced to the near plane, covers the frame ten
times over in the image-space model where the lens gives it 23 %); no one pass can be right there,
and the refinement is (docs/BENCHMARKS.md, "Depth of field in places"). Every rule in pixels of blur holds for the
kernel's own blur, which shrinks with a lens cell, so that every refinement stage is planned as its
cells need and the stages converge to the lens.

This module is the CPU twin of the GL path (rendering/sliced.py), pass for pass: images are in
GL orientation there (rows from the bottom), so :func:`sliced_image` flips its inputs, and blocks
of a reduced level align at the bottom-left corner as the GL targets do.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering.depth_order import camera_depths
from dofview.rendering.footprint import clip_boxes, project
from dofview.tonemap import decode, encode


@dataclass(frozen=True)
class SliceRule:
    """How splats are cut into layers by signed CoC c (pixels), and how far each is blurred at full
    resolution.

    Attributes:
        width: width of the layer around the focus plane, px of CoC (it spans [−width/2, width/2]).
        growth: each layer farther from focus is this factor wider than the one before (≥ 1):
            uniform in 1/z near focus, a relative step where the blur is large.
        huge: |c|, as a fraction of the frame's larger side, from which splats leave the layers
            for the per-splat front and back layers (inf keeps every splat in a layer). The
            whole frame (1): sliced, such splats veil a room (a grazing wall beside the lens);
            drawn per splat, a frame-filling wall at the lens turns to fog, as energy
            normalisation spreads its opaque splats thin (at a quarter of the frame a wall with
            half the frame of blur did; docs/BENCHMARKS.md, "Depth of field in places").
        limit: largest blur radius px gathered at full resolution; a layer blurred further
            blurs at the 1/2ᵏ resolution that brings its smallest radius to ≤ limit.
        spread: β, the variance (px², per axis, per s² − 1) that the box average and the bilinear
            upsampling of a 1/s level add; each radius there is shrunk by it: r′² = r² − 4β(s² − 1).
        guard: the widest guard band, as a fraction of the frame's larger side (:func:`guard_band`).
        snap: how far an edge between layers may move, as a fraction of the narrower of its two
            layers, to fall into the widest gap between the splats' CoCs there (:func:`snap_edges`).
        bright: a pixel of a reduced layer whose light (its largest channel in the blend space) is
            more than this many times the mean of the blocks of its level around its own
            (:func:`highlight_share`) starts to be drawn as a full-resolution sprite, wholly at
            twice that.
        excess: likewise for light exceeding that mean by more than this (radiance far above 1: an
            HDR source, whose edge a coarse level would show as blocks), wholly at twice that.
        dim: light below which a pixel is no highlight, whatever its neighbourhood (the
            faint fringes of a thin layer), and a full one only from twice that.
        sprites: the most sprites a frame draws, as a fraction of its pixels (0: none); the
            highlights beyond it stay in their layer's gather.
        sprite_blur: the largest blur of a layer whose highlights become sprites, as a fraction of
            the frame's larger side in px of the kernel's blur (:func:`has_sprites`): a sprite draws
            its whole kernel, and a layer blurred further (a wall beside the lens) has highlights
            by the thousand, each covering much of the frame (15.8× the pinhole frame on a corridor
            view without this limit, 5.5× with it; docs/BENCHMARKS.md, "Depth of field in places").
    """

    width: float = 1.0
    growth: float = 1.15
    huge: float = 1.0
    limit: float = 3.0
    spread: float = 1.0 / 6.0
    guard: float = 0.125
    snap: float = 0.3
    bright: float = 8.0
    excess: float = 1.0
    dim: float = 0.01
    sprites: float = 0.02
    sprite_blur: float = 0.25

    def __post_init__(self) -> None:
        if not (math.isfinite(self.width) and self.width > 0):
            raise DofviewError(f"slice width must be a finite number of pixels > 0, got {self.width}")
        if not (math.isfinite(self.growth) and self.growth >= 1.0):
            raise DofviewError(f"slice growth must be a finite factor ≥ 1, got {self.growth}")
        if not self.huge > 0.0:
            raise DofviewError(f"huge-CoC threshold must be a fraction of the frame > 0, got {self.huge}")
        if not (math.isfinite(self.limit) and self.limit >= 1.0):
            raise DofviewError(f"full-resolution blur limit must be a finite radius ≥ 1 px, got {self.limit}")
        if not (math.isfinite(self.spread) and self.spread >= 0.0):
            raise DofviewError(f"level spread must be a finite variance ≥ 0, got {self.spread}")
        if not 0.0 <= self.snap < 0.5:
            raise DofviewError(f"edge snap must be a fraction in [0, ½), got {self.snap}")
        if not (math.isfinite(self.guard) and self.guard >= 0.0):
            raise DofviewError(f"guard band must be a finite fraction of the frame ≥ 0, got {self.guard}")
        for name in ("bright", "excess", "dim"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0.0):
                raise DofviewError(f"highlight {name} threshold must be a finite number > 0, got {getattr(self, name)}")
        if not 0.0 <= self.sprites <= 1.0:
            raise DofviewError(f"sprite cap must be a fraction of the frame's pixels in [0, 1], got {self.sprites}")
        if not self.sprite_blur >= 0.0:
            raise DofviewError(f"sprite blur limit must be a fraction of the frame ≥ 0, got {self.sprite_blur}")


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


def slice_edges(c_min: float, c_max: float, rule: SliceRule, frame: float = math.inf) -> np.ndarray:
    """(K + 1,) float64 layer edges in signed CoC px, descending (front to back), covering
    [max(c_min, −H), min(c_max, H)], H = huge·``frame`` (``frame``: the frame's larger side in
    px of the kernel's blur, :func:`plan_layers`): the focus layer [−w/2, w/2], then layers of
    width w·g, w·g², … outwards on either side. Layer i spans edges[i] ≥ c > edges[i + 1]."""
    huge = rule.huge * frame
    lo, hi = max(c_min, -huge), min(c_max, huge)

    def side(limit: float) -> list[float]:
        out, e, w = [], rule.width / 2, rule.width
        while e < limit:
            w *= rule.growth
            e = min(e + w, huge)
            out.append(e)
        return out

    half = rule.width / 2
    return np.array(side(hi)[::-1] + [half, -half] + [-e for e in side(-lo)], np.float64)


def snap_edges(edges: np.ndarray, c: np.ndarray, snap: float) -> np.ndarray:
    """``edges`` (K + 1,) descending, each inner one moved within ``snap`` of the narrower of its two
    layers to the middle of the widest gap between the CoCs ``c`` (N,) px of the splats (in draw
    order: descending, or nearly for an earlier view's order) there. Blurred layers composite as if
    independent; an object cut between two of them is blurred as two (a cluster of leaves cut in
    half loses 6 dB against the lens; docs/BENCHMARKS.md), so cuts go where the splats leave room."""
    out = edges.copy()
    if snap <= 0.0 or len(c) == 0:
        return out
    neg = -np.asarray(c, np.float64)
    for i in range(1, len(edges) - 1):
        d = snap * min(edges[i - 1] - edges[i], edges[i] - edges[i + 1])
        hi, lo = edges[i] + d, edges[i] - d
        i0, i1 = np.searchsorted(neg, -hi, side="left"), np.searchsorted(neg, -lo, side="right")
        inside = np.sort(np.asarray(c[i0:i1], np.float64))
        points = np.concatenate([[lo], inside[(inside > lo) & (inside < hi)], [hi]])
        j = int(np.argmax(np.diff(points)))
        out[i] = 0.5 * (points[j] + points[j + 1])
    return out


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


@dataclass(frozen=True)
class LayerStats:
    """What a frame's plan measures of its Gaussians, the GPU (rendering/layer_plan.py) and numpy
    (:func:`measure_layers`) alike; the layers, their levels and the guard band follow from it in
    O(layers) (:func:`layers_of`, :func:`frame_plan`).

    Slots v = −1 … K + 1 of the draw order: −1 the huge-CoC front layer, 0 … K − 1 the slices
    (edges[v] ≥ c > edges[v + 1]), K the huge-CoC back layer, K + 1 nothing (the end).

    Attributes:
        edges: (K + 1,) float64 the slices' edges, signed CoC px, descending (:func:`slice_edges`
            over the live Gaussians' range, then :func:`snap_edges`).
        bounds: (K + 3,) int64 slot v's first place in the draw order at bounds[v + 1]; slot v is
            [bounds[v + 1], bounds[v + 2]), and the places before bounds[0] are culled (z ≤ near).
        lo, hi: (K,) float64 per slice the smallest and largest |c| px of its live Gaussians (NaN
            in an empty slice).
        boxes: (K, 4) int64 per slice its screen box (:func:`screen_boxes`; an empty slice's holds
            :data:`NO_BOX`), or None where the plan has no camera (:func:`plan_layers`).
    """

    edges: np.ndarray
    bounds: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    boxes: np.ndarray | None = None

    @property
    def k(self) -> int:
        """K, the slices (0, with no edges and no slots, when no Gaussian lies beyond the near plane)."""
        return max(len(self.edges) - 1, 0)


NO_BOX = (2**31 - 1, 2**31 - 1, -2**31, -2**31)
"""The box of an empty slice (what min/max over no Gaussian leave)."""


def measure_layers(depth: np.ndarray, lens: Lens, near: float, rule: SliceRule = SliceRule(),
                   frame: float = math.inf, current: bool = True) -> LayerStats:
    """The slots and CoC ranges (:class:`LayerStats`, without boxes) of Gaussians at camera depths
    ``depth`` (N,) float32 scene units in draw order, nearest first; those at z ≤ ``near`` (culled)
    join the layer before them. ``frame``: the frame's larger side in px of the kernel's blur
    (px / the kernel's size, :func:`layers_of`), which SliceRule.huge is a fraction of.
    ``current``: the order is sorted for these depths; else it was sorted for an earlier view (the viewer's background sort), is nearly sorted, and each Gaussian takes the
    farthest layer of those before it, so the ranges stay contiguous; its edges stay on the
    lattice (:func:`snap_edges` needs the depths sorted)."""
    depth = np.asarray(depth, np.float64)
    live = depth > near
    if not live.any():
        return LayerStats(np.zeros(0), np.zeros(0, np.int64), np.zeros(0), np.zeros(0))
    c = signed_coc(depth[live], lens)
    edges = slice_edges(float(c.min()), float(c.max()), rule, frame)
    if current:
        edges = snap_edges(edges, c, rule.snap)
    k = len(edges) - 1
    # descending edges: count the edges strictly above c (np.searchsorted wants ascending)
    index = np.clip(k - np.searchsorted(edges[::-1], c, side="left"), 0, k - 1)
    huge = rule.huge * frame
    index = np.where(c > huge, -1, np.where(c < -huge, k, index))
    key = np.full(len(depth), -2, np.int64)  # -2: culled; -1 the front layer, 0…k−1 the slices, k the back layer
    key[live] = index
    key = np.maximum.accumulate(key)
    bounds = np.searchsorted(key, np.arange(-1, k + 2), side="left")
    coc = np.full(len(depth), np.nan)  # culled: in no layer's range of blur
    coc[live] = np.abs(c)
    lo, hi = np.full(k, np.nan), np.full(k, np.nan)
    for v in range(k):
        part = coc[bounds[v + 1]:bounds[v + 2]]
        if part.size:  # (its first Gaussian is live: it raised the running slot)
            lo[v], hi[v] = np.nanmin(part), np.nanmax(part)
    return LayerStats(edges, bounds.astype(np.int64), lo, hi)


def layers_of(stats: LayerStats, rule: SliceRule, size: float = 1.0) -> list[Layer]:
    """The non-empty layers of ``stats``, front to back. ``size``: the kernel's scale against the
    whole aperture's (√share of a lens cell: its equal-area disk), which sets each layer's
    resolution: a small cell's shape needs a finer level."""
    k, bounds = stats.k, stats.bounds
    layers = []
    for v in range(-1, k + 1) if len(bounds) else ():
        first, end = int(bounds[v + 1]), int(bounds[v + 2])
        if end <= first:
            continue
        if v in (-1, k):
            layers.append(Layer(first, end, True, 0.0, 1))
            continue
        lo, hi = float(stats.lo[v]), float(stats.hi[v])
        # the level by the layer's *smallest* blur: where a surface runs from one layer into the
        # next, both blur it alike only if the farther layer's level still resolves its nearest
        # pixels (by the largest, a floor shows a band at every change of level); but no finer
        # than brings the largest to limit + 2 (an earlier view's order mixes blurs in a layer)
        scale = max(rule.scale(lo * size), replace(rule, limit=rule.limit + 2.0).scale(hi * size))
        layers.append(Layer(first, end, False, hi, scale))
    return layers


def plan_layers(depth: np.ndarray, lens: Lens, near: float, rule: SliceRule = SliceRule(),
                size: float = 1.0, frame: float = math.inf, current: bool = True) -> list[Layer]:
    """The non-empty layers, front to back, of Gaussians at camera depths ``depth`` (N,) scene
    units in draw order (:func:`measure_layers`, :func:`layers_of`)."""
    return layers_of(measure_layers(depth, lens, near, rule, frame, current), rule, size)


Box = tuple[int, int, int, int]
"""(x0, y0, x1, y1) pixels, ends exclusive; rows from the top unless said otherwise."""
GUARD_STEP = 32
"""The guard band's smallest width px; wider bands double it (so that the targets sized by it are
made again only when the band's need changes by a factor of two)."""
GUARD_MIN_REACH = 8
"""Layers whose blur reaches less than this many px (the focus layers) do not ask for a guard band:
repeating the frame's edge serves them."""


def guard_cap(rule: SliceRule, width: int, height: int) -> int:
    """The widest guard band px a frame of ``width`` × ``height`` may get (:attr:`SliceRule.guard` of
    its larger side, rounded up to :data:`GUARD_STEP`)."""
    return -(-int(rule.guard * max(width, height)) // GUARD_STEP) * GUARD_STEP


def screen_boxes(scene, order: np.ndarray, camera: Camera, lens: Lens, settings: RenderSettings,
                 bounds: np.ndarray, rule: SliceRule) -> np.ndarray:
    """(K, 4) int64 per slice of ``bounds`` (LayerStats.bounds) the pixels its blend can touch,
    (x0, y0, x1, y1) image pixels of ``camera``, rows from the top, ends exclusive, *not* clipped
    to the frame (the guard band needs to know how far a layer reaches beyond it) but to the widest
    guard band around it (:func:`guard_cap`): the union over its Gaussians of the part of each
    one's footprint, as the pinhole blends it (``lens`` focused, A = 0, ``settings``), in that
    rectangle (footprint.clip_boxes), and a pixel of margin; :data:`NO_BOX` for an empty slice.
    A splat near the lens can be an ellipse thousands of pixels wide whose box covers the frame
    while it draws in a corner of it or nowhere: boxes of whole footprints (or, as before, of 3σ
    of the largest scale) made a room's layers work on 2–5 times the pixels they draw in.
    Float64 (glsl/plan_stats.comp is the float32 twin: within a pixel)."""
    w, h = camera.width, camera.height
    k = max(len(bounds) - 3, 0)
    out = np.tile(np.array(NO_BOX, np.int64), (k, 1))
    starts, ends = np.asarray(bounds[1:k + 1], np.int64), np.asarray(bounds[2:k + 2], np.int64)
    full = np.flatnonzero(ends > starts)
    if not len(full):
        return out
    cap = guard_cap(rule, w, h)
    pr = project(scene, camera, Lens(lens.focus, 0.0), replace(settings, dof="splat"))
    clipped = clip_boxes(pr["mean2d"], pr["cov"], pr["det"], pr["r2"], (-cap, -cap, w + cap, h + cap))
    box = np.tile(np.array([np.inf, np.inf, -np.inf, -np.inf]), (len(scene.means), 1))
    hit = (clipped[:, 0] <= clipped[:, 2]) & (clipped[:, 1] <= clipped[:, 3])
    box[pr["idx"][hit]] = np.concatenate([np.floor(clipped[hit, :2]) - 1, np.ceil(clipped[hit, 2:]) + 2], 1)
    first = int(starts[full[0]])
    part = box[order[first:int(ends[full[-1]])]]
    seg = starts[full] - first  # the non-empty slices are contiguous: reduceat over their starts
    lo, hi = np.minimum.reduceat(part[:, :2], seg, axis=0), np.maximum.reduceat(part[:, 2:], seg, axis=0)
    drawn = np.isfinite(lo[:, 0])
    out[full[drawn]] = np.concatenate([lo[drawn], hi[drawn]], 1).astype(np.int64)
    return out


def layer_reach(layer: Layer) -> int:
    """Pixels beyond a layer's own pixels that its blur can reach: its largest radius, a block of
    its level for the reduction and one for the bilinear upsampling."""
    return 0 if layer.lensed else math.ceil(layer.radius) + 2 * layer.scale


def guard_band(layers: list[Layer], boxes: list[Box], width: int, height: int, rule: SliceRule) -> int:
    """Pixels of guard band to render beyond the frame on every side: what the layers' blurs need
    of what lies beyond it (each layer: its overhang beyond the frame, ``boxes`` as
    :func:`screen_boxes` gives them, up to its reach), in steps doubling from
    :data:`GUARD_STEP`, at most :attr:`SliceRule.guard` of the frame's larger side (beyond the band
    the gather repeats its edge). 0 when no layer blurred by :data:`GUARD_MIN_REACH` px or more
    reaches beyond the frame."""
    if rule.guard == 0.0:
        return 0
    need = 0
    for layer, (x0, y0, x1, y1) in zip(layers, boxes):
        reach = layer_reach(layer)
        if reach >= GUARD_MIN_REACH:
            need = max(need, min(max(-x0, -y0, x1 - width, y1 - height, 0), reach))
    if need == 0:
        return 0
    cap = guard_cap(rule, width, height)
    band = GUARD_STEP
    while band < need:
        band *= 2
    return min(band, cap)


Edges = tuple[bool, bool, bool, bool]
"""Per side of a layer's image, GL orientation (left, bottom, right, top): the gather repeats the
edge beyond it (True: the layer's content goes on beyond what was rendered) or reads nothing."""


def layer_edges(boxes: list[Box], width: int, height: int, guard: int) -> list[Edges]:
    """Per layer, which sides of the guarded image (the frame of ``width`` × ``height`` and
    ``guard`` pixels on every side) its box (``boxes``, frame pixels, rows from the top) reaches
    beyond: there the gather repeats the edge (a wall goes on), elsewhere it reads nothing (what
    lies beyond a layer's own pixels is empty; repeating it would spread an inner block of a
    coarse level over the whole kernel)."""
    return [(x0 < -guard, y1 > height + guard, x1 > width + guard, y0 < -guard) for x0, y0, x1, y1 in boxes]


def layer_windows(layers: list[Layer], boxes: list[Box], width: int, height: int, guard: int) -> list[Box]:
    """Per layer the pixels of the guarded image (the frame of ``width`` × ``height`` and ``guard``
    pixels on every side; rows from the top) where it is blended: its box (``boxes``, frame
    pixels), within its reach of the frame (what lies farther cannot blur into it) and inside the
    guarded image. Both paths blend a layer there only (the GL backends cut at it)."""
    out = []
    for layer, (x0, y0, x1, y1) in zip(layers, boxes):
        band = min(guard, layer_reach(layer)) if not layer.lensed else guard
        lo, hx, hy = guard - band, guard + width + band, guard + height + band
        out.append((max(x0 + guard, lo), max(y0 + guard, lo), min(x1 + guard, hx), min(y1 + guard, hy)))
    return out


@dataclass(frozen=True)
class FramePlan:
    """What the sliced mode draws of one frame, the GL path and the CPU twin alike.

    Attributes:
        layers: the layers, front to back (:func:`plan_layers`).
        guard: pixels of guard band on every side of the frame (:func:`guard_band`).
        windows: per layer the pixels of the guarded image where it is blended (:func:`layer_windows`).
        edges: per layer the sides beyond which its gather repeats the edge (:func:`layer_edges`).
    """

    layers: list[Layer]
    guard: int
    windows: list[Box]
    edges: list[Edges]

    @property
    def pinhole(self) -> bool:
        """One unblurred layer (A = 0): the frame is the pinhole's."""
        return len(self.layers) == 1 and not self.layers[0].lensed and self.layers[0].radius == 0.0


def pinhole_plan(count: int, width: int, height: int) -> FramePlan:
    """The plan at A = 0, made without looking at a Gaussian: one unblurred layer, the whole draw
    order of ``count`` Gaussians (those behind the near plane are culled as the pinhole culls them),
    drawn whole into a frame of ``width`` × ``height``."""
    return FramePlan([Layer(0, count, False, 0.0, 1)], 0, [(0, 0, width, height)], [(True,) * 4])


def frame_plan(stats: LayerStats, camera: Camera, rule: SliceRule, size: float = 1.0) -> FramePlan:
    """The sliced mode's plan of a frame of ``camera`` from what was measured of its Gaussians
    (``stats``, with boxes), for a kernel of ``size`` (:func:`layers_of`): O(layers), the same
    for the GPU's plan and numpy's. A pinhole frame (:attr:`FramePlan.pinhole`) gets no boxes: it is
    drawn whole."""
    w, h = camera.width, camera.height
    layers = layers_of(stats, rule, size)
    whole = FramePlan(layers, 0, [(0, 0, w, h)] * len(layers), [(True,) * 4] * len(layers))
    if not layers or whole.pinhole:
        return whole
    slice_boxes = iter(tuple(int(x) for x in b) for b, first, end in zip(stats.boxes, stats.bounds[1:], stats.bounds[2:])
                       if end > first)
    boxes = [(0, 0, w, h) if layer.lensed else next(slice_boxes) for layer in layers]
    guard = guard_band(layers, boxes, w, h, rule)
    return FramePlan(layers, guard, layer_windows(layers, boxes, w, h, guard), layer_edges(boxes, w, h, guard))


def plan_frame(scene, order: np.ndarray, camera: Camera, lens: Lens, settings: RenderSettings,
               rule: SliceRule, size: float = 1.0, current: bool = True) -> FramePlan:
    """The sliced mode's plan of a frame of ``scene`` seen by ``camera`` in the draw order ``order``
    (N,) (nearest first; ``current``: sorted for this view, :func:`measure_layers`), ``settings``
    (its near plane, and the footprints' rules), for a kernel of ``size`` (:func:`frame_plan`): the
    numpy twin of the GPU's (rendering/layer_plan.py). At A = 0 no Gaussian is looked at
    (:func:`pinhole_plan`)."""
    w, h = camera.width, camera.height
    if lens.aperture == 0.0:
        return pinhole_plan(len(order), w, h)
    stats = measure_layers(camera_depths(scene.means, camera)[order], lens, settings.near, rule, max(w, h) / size,
                           current)
    stats = replace(stats, boxes=screen_boxes(scene, order, camera, lens, settings, stats.bounds, rule))
    return frame_plan(stats, camera, rule, size)


# ---- the aperture ----------------------------------------------------------------------------------
NORM_SAMPLES = 2048
"""Samples per sign and range of the kernels' N(ρ) tables (LensCell.norms)."""
NORM_FINE = 2.0
"""|ρ| (level px) up to which slice_blur.glsl reads N(ρ) from a fine table: where N is small,
its kinks (every tap's ramp starts and ends) weigh most against it."""
LEVEL_RADIUS = 8.5
"""The largest blur radius (px) a layer has at its level (plan_layers: the rule's limit + 2, 8 with
blades, and a little more), for which each cell's LensCell.tap_onsets are made at once."""


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
        """The whole aperture as one cell, seen from its centre: the single pass's kernel (one
        object per aperture, so that what is made for it, such as its N(ρ) tables, is made once)."""
        return _whole(self)


@functools.lru_cache(maxsize=64)
def _whole(aperture: Aperture) -> "LensCell":
    return LensCell(aperture.planes(), not aperture.blades, np.zeros(2), 1.0, 1.0)


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
        return self._gl

    @functools.cached_property
    def _gl(self) -> tuple[np.ndarray, np.ndarray]:
        flip = np.array([1.0, -1.0])
        pl = np.array(self.planes, np.float64).reshape(-1, 3)
        return _frozen((self.point * flip).astype(np.float32)), _frozen(
            np.concatenate([pl[:, :2] * flip, pl[:, 2:]], 1).astype(np.float32))

    def weights(self, d: np.ndarray, rho: np.ndarray) -> np.ndarray:
        """(T, …) float32 w(d, ρ) of offsets ``d`` (T, 2) px, GL orientation, for sources of
        signed CoC ``rho`` (…) px (slice_kernel.glsl is the twin); ρ = 0 is the identity."""
        rho = np.asarray(rho, np.float32)
        ex = (slice(None),) + (None,) * rho.ndim
        return self._weight(np.asarray(d[:, 0], np.float32)[ex], np.asarray(d[:, 1], np.float32)[ex], rho[None])

    def _weight(self, dx: np.ndarray, dy: np.ndarray, rho: np.ndarray) -> np.ndarray:
        """w of offsets (``dx``, ``dy``) for sources of signed CoC ``rho``, float32 arrays broadcast
        together."""
        point, planes = self.gl()
        a = np.abs(rho)
        sgn = np.where(rho < 0, np.float32(-1.0), np.float32(1.0))
        vx = a * point[0] - sgn * dx  # |ρ|·u in px, u = point − d/ρ
        vy = a * point[1] - sgn * dy
        sd = np.sqrt(vx * vx + vy * vy) - a if self.disk else np.full(np.broadcast(vx, a).shape, -np.inf, np.float32)
        for nx, ny, h in planes:
            sd = np.maximum(sd, vx * nx + vy * ny - a * h)
        return np.clip(np.float32(0.5) - sd, 0.0, 1.0).astype(np.float32)

    def onsets(self, taps: np.ndarray, radius: float) -> np.ndarray:
        """(T,) float32 for each offset of ``taps`` (T, 2) px, GL orientation, that sources of
        |ρ| = ``radius`` px reach: a |ρ| below which no source, in front of focus or behind it,
        gives it weight (w(d, ±a) = 0 for every a ≤ onset; 0 for the centre), within a millionth
        of ``radius`` of the least such. A kernel's signed distance never grows with |ρ|
        (``point`` lies in the cell), so the offsets a source of |ρ| ≤ a can reach are those of
        onset < a: the gather of a tile whose sources are all that sharp stops at the first tap
        beyond (sliced.py)."""
        d = np.asarray(taps, np.float32)
        lo, hi = np.zeros(len(d), np.float32), np.full(len(d), np.float32(radius))

        def reached(a: np.ndarray) -> np.ndarray:
            return np.maximum(self._weight(d[:, 0], d[:, 1], a), self._weight(d[:, 0], d[:, 1], -a)) > 0

        for _ in range(20):  # lo: no weight at |ρ| ≤ lo (or the centre's 0); hi: weight
            mid = ((lo + hi) * np.float32(0.5)).astype(np.float32)
            hit = reached(mid)
            hi, lo = np.where(hit, mid, hi), np.where(hit, lo, mid)
        return np.where(reached(np.zeros(len(d), np.float32)), np.float32(0.0), lo).astype(np.float32)

    def norms(self, radius: float, samples: int = NORM_SAMPLES) -> np.ndarray:
        """(2, samples) float32 the kernel's N(ρ) = Σ_taps w(d, ρ) at ρ = radius·i/(samples − 1),
        i = 0 … samples − 1 (row 0: in front of focus) and at −ρ (row 1: behind it): the table that
        slice_blur.glsl interpolates linearly instead of summing every tap per texel (one over
        [0, :data:`NORM_FINE`], one over the frame's whole range; tests hold them within 1e-3 of
        N)."""
        taps = self.taps(radius)
        rho = np.linspace(0.0, radius, samples, dtype=np.float32)
        return np.stack([self.weights(taps, rho).sum(axis=0, dtype=np.float64),
                         self.weights(taps, -rho).sum(axis=0, dtype=np.float64)]).astype(np.float32)

    def taps(self, radius: float) -> np.ndarray:
        """(T, 2) float32 the offsets (GL orientation) where the kernel of a source of |ρ| ≤
        ``radius`` px has weight, nearest first (the kernels of smaller |ρ| lie inside); read-only,
        made once per cell and radius (a sliced frame asks for them per layer, and again every
        frame)."""
        return _taps(self, float(radius))[0]

    def tap_onsets(self, radius: float) -> np.ndarray:
        """(T,) float32 :meth:`onsets` of :meth:`taps` (``radius``), made once per cell and grid of
        candidate offsets."""
        return _taps(self, float(radius))[1]


@functools.lru_cache(maxsize=4096)  # a frame's layers, for the cells of a refinement stage
def _taps(cell: LensCell, radius: float) -> tuple[np.ndarray, np.ndarray]:
    n = int(math.ceil(cell.reach * max(radius, 0.0) + 1.5))
    d = _offsets(n)
    reach = np.max(cell.weights(d, np.array([radius, -radius], np.float32)), axis=1) > 0
    reach[0] = True  # the centre, whatever the cell
    return _frozen(d[reach]), _frozen(_grid_onsets(cell, n)[reach])


def _grid_onsets(cell: LensCell, n: int) -> np.ndarray:
    """LensCell.onsets of every offset of :func:`_offsets` (``n``), looked up in the cell's table
    (made once for the taps of the largest blur a layer has at its level, or for ``n`` beyond)."""
    big = max(n, int(math.ceil(cell.reach * LEVEL_RADIUS + 1.5)))
    d = _offsets(n).astype(np.int64)
    return _onset_table(cell, big)[d[:, 1] + big, d[:, 0] + big]


@functools.lru_cache(maxsize=1024)  # the cells of a refinement stage
def _onset_table(cell: LensCell, n: int) -> np.ndarray:
    """(2n + 1, 2n + 1) float32 LensCell.onsets of every offset within ±``n`` px, at [y + n, x + n],
    up to the largest radius whose taps that grid holds (an offset no such source reaches gets that
    radius)."""
    d = _offsets(n)
    table = np.empty((2 * n + 1, 2 * n + 1), np.float32)
    table[d[:, 1].astype(np.int64) + n, d[:, 0].astype(np.int64) + n] = cell.onsets(
        d, max((n - 1.5) / max(cell.reach, 1e-6), 0.0))
    return _frozen(table)


@functools.lru_cache(maxsize=64)
def _offsets(n: int) -> np.ndarray:
    """(T, 2) float32 the integer offsets within ±``n`` px, nearest first (then by y, by x)."""
    dy, dx = np.mgrid[-n:n + 1, -n:n + 1]
    d = np.stack([dx.ravel(), dy.ravel()], 1).astype(np.float32)
    return _frozen(d[np.lexsort((d[:, 0], d[:, 1], np.hypot(d[:, 0], d[:, 1])))])


def _frozen(a: np.ndarray) -> np.ndarray:
    """``a`` made read-only: it is cached and shared."""
    a.flags.writeable = False
    return a


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
            rule: SliceRule, cell: LensCell, taps: np.ndarray,
            budget: int = 0) -> tuple[np.ndarray, np.ndarray, Sprites | None]:
    """One layer made ready for its gather at its level 1/s (slice_visible.comp, slice_reduce.frag,
    slice_prepare.frag and slice_blur.glsl).

    ``colour`` (H, W, 4) its blend-space premultiplied RGBA, ``depth_sums`` (H, W, 4) its
    (Σw·z, Σw/z, 0, Σw); ``acc_depth`` (H, W, 4) float64 the depth sums of the layers in front,
    to which this layer's are added under their transmittance T (in place): the pinhole's depth.
    The layer's visible coverage V·α rides along with its depth sums through the 2 × 2 averages
    (:func:`reduce2`) down to the level, V the transmittance of the layers in front, kept in the
    accumulator's third component. A reduced layer's highlights (:func:`highlights`: at most
    ``budget`` of them) leave it for sprites first. Returns ``a`` (h, w, 4) the level's colour
    over N(ρ) = Σ_taps w(d, ρ) of each texel's signed CoC ρ (level px, shrunk: see the module
    docstring), ``b`` (h, w, 2) (ρ, visible coverage / N(ρ)) and the sprites (None: none)."""
    trans = 1.0 - acc_depth[..., 3]
    col = np.asarray(colour, np.float64)
    visible = (1.0 - acc_depth[..., 2]) * col[..., 3]
    acc_depth += trans[..., None] * depth_sums
    acc_depth[..., 2] += visible
    dep = np.array(depth_sums, np.float64)
    dep[..., 2] = visible
    s = layer.scale
    sprites = None
    if s > 1 and not layer.lensed and budget > 0:
        sprites = highlights(col, dep, lens, layer, rule, budget)
        col = col.copy()
        col[sprites.y, sprites.x] -= sprites.colour
        dep[sprites.y, sprites.x] -= sprites.share[:, None] * dep[sprites.y, sprites.x]
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
    return col / norm[..., None], np.stack([rho, dep[..., 2] / norm], -1), sprites


# ---- highlights: sprites at full resolution --------------------------------------------------------
@dataclass(frozen=True)
class Sprites:
    """A layer's highlights, each drawn at full resolution as its own kernel instead of through the
    layer's reduced level (where a small bright source becomes a soft, blocky blob).

    Attributes:
        x, y: (M,) int64 pixels of the layer's image, GL orientation (rows from the bottom).
        colour: (M, 4) float64 the light each takes out of its pixel, blend-space premultiplied RGBA.
        share: (M,) float64 the share f of its pixel's light (and depth sums) it takes.
        rho: (M,) float32 its pixel's signed CoC px (full resolution, within the layer's radius).
        visible: (M,) float64 its part of the pixel's visible coverage.
    """

    x: np.ndarray
    y: np.ndarray
    colour: np.ndarray
    share: np.ndarray
    rho: np.ndarray
    visible: np.ndarray

    def __len__(self) -> int:
        return len(self.x)


def brightness(colour: np.ndarray) -> np.ndarray:
    """(…) float64 the light of blend-space colours ``colour`` (…, 4) as the gather spreads it: the
    largest channel (display-encoded for an sRGB scene, radiance for an HDR one)."""
    return np.max(np.maximum(np.asarray(colour, np.float64)[..., :3], 0.0), axis=-1)


def highlight_share(colour: np.ndarray, level: np.ndarray, scale: int, rule: SliceRule) -> np.ndarray:
    """(H, W) float64 the share f of each pixel's light of a layer (``colour`` (H, W, 4),
    blend-space, GL orientation) drawn as a sprite: its brightness L (:func:`brightness`) against
    the mean B of the brightness of the 8 texels of ``level`` (h, w, 4: the layer averaged to
    1/``scale``) around its own (those inside the level), the layer's light around the block the
    level blends it with, f = max(clip(L/(bright·B) − 1), clip((L − B)/excess − 1)) ·
    clip(L/dim − 1), each clipped to [0, 1] (SliceRule): 1 for a source within its block and
    bright against the blocks around (a point, a small cluster, an HDR source's rim), 0 on an even
    surface (slice_prepare.frag)."""
    lum, lev = brightness(colour), brightness(level)
    h, w = lev.shape
    padded, inside = np.pad(lev, 1), np.pad(np.ones((h, w)), 1)
    around = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dy or dx]
    total = sum(padded[1 + dy:1 + dy + h, 1 + dx:1 + dx + w] for dy, dx in around)
    count = sum(inside[1 + dy:1 + dy + h, 1 + dx:1 + dx + w] for dy, dx in around)
    rows, cols = np.arange(lum.shape[0]) // scale, np.arange(lum.shape[1]) // scale
    mean = (total / np.maximum(count, 1.0))[rows[:, None], cols[None, :]]
    kb = rule.bright * mean
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(kb > 0, np.clip(lum / np.where(kb > 0, kb, 1.0) - 1.0, 0.0, 1.0), 1.0)
    excess = np.clip((lum - mean) / rule.excess - 1.0, 0.0, 1.0)
    return np.maximum(ratio, excess) * np.clip(lum / rule.dim - 1.0, 0.0, 1.0)


def highlights(colour: np.ndarray, depth_sums: np.ndarray, lens: Lens, layer: Layer, rule: SliceRule,
               budget: int) -> Sprites:
    """The sprites of a reduced layer (``colour`` (H, W, 4) blend-space, ``depth_sums`` (H, W, 4)
    with its visible coverage third, GL orientation): every pixel with a share
    (:func:`highlight_share`) > 0 and blending weight, in raster order (rows from the bottom); none
    if there are more than ``budget`` (what is left of the frame's cap: a layer's highlights are
    drawn all or none, as sprite_accept.comp keeps or refuses those slice_prepare.frag appended, so
    that no order of the GPU's chooses among them)."""
    s = layer.scale
    level = colour
    for _ in range(s.bit_length() - 1):
        level = reduce2(level)
    share = highlight_share(colour, level, s, rule)
    y, x = np.nonzero((share > 0) & (depth_sums[..., 3] > 0))
    if len(y) > budget:
        y, x = y[:0], x[:0]
    f, d = share[y, x], depth_sums[y, x]
    c = (np.float32(0.5 * lens.aperture) * (d[:, 1] / d[:, 3] - np.float32(lens.inv_focus))).astype(np.float32)
    rho = np.copysign(np.minimum(np.abs(c), np.float32(layer.radius)), c).astype(np.float32)
    return Sprites(x, y, f[:, None] * colour[y, x], f, rho, f * d[:, 2])


def has_sprites(layer: Layer, rule: SliceRule, cap: int, frame: float) -> bool:
    """Whether ``layer``'s highlights may leave it as sprites: a reduced layer drawn sliced, in a
    frame whose cap (:func:`sprite_cap`) allows any, blurred by at most SliceRule.sprite_blur of
    ``frame`` (the frame's larger side in px of the kernel's blur, as for SliceRule.huge). Such a
    layer is composited as a run of its own (the GL path and :func:`sliced_image` alike)."""
    return cap > 0 and layer.scale > 1 and not layer.lensed and layer.radius <= rule.sprite_blur * frame


def sprite_cap(rule: SliceRule, width: int, height: int) -> int:
    """The most sprites a frame of ``width`` × ``height`` pixels draws (SliceRule.sprites of them)."""
    return int(rule.sprites * width * height)


def draw_sprites(sprites: Sprites, cell: LensCell, h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """Each sprite spread at full resolution over the kernel of ``cell`` for its own signed CoC,
    w(d, ρ)/N with N = Σ_d w(d, ρ) over every offset (so each keeps its light), into an image
    (h, w, 4) float64 and its visible coverage (h, w), GL orientation (slice_sprite.vert/.frag)."""
    out, vis = np.zeros((h, w, 4)), np.zeros((h, w))
    for x, y, colour, rho, visible in zip(sprites.x, sprites.y, sprites.colour, sprites.rho, sprites.visible):
        n = int(math.ceil(cell.reach * abs(float(rho)) + 1.5))
        dy, dx = np.mgrid[-n:n + 1, -n:n + 1]
        wt = cell.weights(np.stack([dx.ravel(), dy.ravel()], 1).astype(np.float32), rho).astype(np.float64)
        wt = (wt / wt.sum()).reshape(dy.shape)
        y0, y1, x0, x1 = max(y - n, 0), min(y + n + 1, h), max(x - n, 0), min(x + n + 1, w)
        part = wt[y0 - (y - n):y1 - (y - n), x0 - (x - n):x1 - (x - n)]
        out[y0:y1, x0:x1] += part[..., None] * colour
        vis[y0:y1, x0:x1] += part * visible
    return out, vis


def reduce2(x: np.ndarray) -> np.ndarray:
    """(⌈h/2⌉, ⌈w/2⌉, …) averages of the 2 × 2 blocks of ``x`` (h, w, …) from the origin, each
    over the texels of its block inside ``x`` (slice_reduce.frag)."""
    h, w = x.shape[:2]
    ph, pw = h % 2, w % 2
    pad = ((0, ph), (0, pw)) + ((0, 0),) * (x.ndim - 2)
    sums = np.pad(np.asarray(x, np.float64), pad).reshape((h + ph) // 2, 2, (w + pw) // 2, 2, *x.shape[2:])
    count = np.pad(np.ones((h, w)), pad[:2]).reshape((h + ph) // 2, 2, (w + pw) // 2, 2).sum(axis=(1, 3))
    return sums.sum(axis=(1, 3)) / count.reshape(count.shape + (1,) * (x.ndim - 2))


def pad_sides(x: np.ndarray, n: int, edges: Edges) -> np.ndarray:
    """``x`` (h, w, …), GL orientation, padded by ``n`` on every side: the edge repeated on the
    sides ``edges`` (left, bottom, right, top) names, zeros elsewhere; a corner is repeated only
    where both of its sides are."""
    left, bottom, right, top = edges
    rest = ((0, 0),) * (x.ndim - 2)
    for axis, (lo, hi) in ((0, (bottom, top)), (1, (left, right))):
        for width, repeat in (((n, 0), lo), ((0, n), hi)):
            pad = ((0, 0), width) if axis else (width, (0, 0))
            x = np.pad(x, pad + rest, mode="edge") if repeat else np.pad(x, pad + rest)
    return x


def scatter(a: np.ndarray, b: np.ndarray, cell: LensCell, taps: np.ndarray,
            edges: Edges = (True,) * 4) -> tuple[np.ndarray, np.ndarray]:
    """The gather (slice_gather.frag): every pixel of ``a`` (h, w, 4) spread over the kernel of
    ``cell`` for its own signed CoC b[…, 0] (level px), its visible coverage b[…, 1] alike, read
    beyond the image as :func:`pad_sides` pads it with ``edges``. Returns the blurred colour
    (h, w, 4) and visible coverage (h, w)."""
    h, w = a.shape[:2]
    n = int(np.abs(taps).max()) if len(taps) else 0
    ap, bp = pad_sides(a, n, edges), pad_sides(b, n, edges)
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
                 rule: SliceRule = SliceRule(), cell: LensCell | None = None,
                 guard: int = 0, edges: list[Edges] | None = None,
                 capture: Callable[[int, np.ndarray], None] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The depth-of-field image from the layers of ``plan`` as blended, front to back: per layer
    (colour (H, W, 4) premultiplied RGBA *in the blend space*, depth sums (H, W, 4) (Σw·z, Σw/z,
    0, Σw)), image orientation (rows downwards), blurred by the kernel of ``cell`` (default: the
    whole disk). The layers are blended over the frame and a guard band of ``guard`` pixels on
    every side (:func:`guard_band`), which the result leaves out; the gather repeats each layer's
    edges as ``edges`` (:func:`layer_edges`; default: every side) says. A reduced layer's
    highlights are drawn as sprites (:func:`highlights`, at most SliceRule.sprites of the frame's
    pixels), added at full resolution to its upsampled image, which is then composited on its own
    (a run of one layer). Returns the colour (H − 2·guard, W − 2·guard, 4) float64 in the blend
    space and the depth sums alike of the pinhole (the layers composited unblurred). ``capture``:
    called after each layer with its index and the frame's "over" so far (H, W, 4) float64, GL
    orientation (a reduced layer's in a run: the frame before its run, over the run so far
    upsampled), the deep image's twin (rendering/deep_sliced.py)."""
    cell = cell or Aperture().whole()
    h, w = layers[0][0].shape[:2]
    over, visible = np.zeros((h, w, 4)), np.zeros((h, w))
    acc_depth = np.zeros((h, w, 4))
    budget = cap = sprite_cap(rule, w - 2 * guard, h - 2 * guard)
    frame = (max(w, h) - 2 * guard) / math.sqrt(cell.share)  # in px of the kernel's blur (has_sprites)
    # [scale, over, visible, sprites' colour, sprites' visible] of the run of reduced layers being
    # composited (the sprites at full resolution)
    run: list[object] = []

    def end_run() -> None:
        nonlocal over, visible
        if run:
            s, r_over, r_vis, s_colour, s_vis = run
            over += (1.0 - over[..., 3:4]) * (upsample(r_over, s, h, w) + s_colour)
            visible += upsample(r_vis, s, h, w) + s_vis
            run.clear()

    for index, ((colour, depth_sums), layer, sides) in enumerate(zip(layers, plan, edges or [(True,) * 4] * len(plan))):
        taps = cell.taps(0.0 if layer.lensed else layer.radius / layer.scale)
        lit = has_sprites(layer, rule, cap, frame)
        a, b, sprites = prepare(np.asarray(colour[::-1], np.float64), np.asarray(depth_sums[::-1], np.float64),
                                acc_depth, lens, layer, rule, cell, taps, budget if lit else 0)
        blurred, vis = scatter(a, b, cell, taps, sides)
        if layer.scale == 1:
            end_run()
            over += (1.0 - over[..., 3:4]) * blurred
            visible += vis
            if capture is not None:
                capture(index, over)
            continue
        if run and run[0] != layer.scale:
            end_run()
        if not run:
            run.extend([layer.scale, np.zeros_like(blurred), np.zeros_like(vis), np.zeros((h, w, 4)), np.zeros((h, w))])
        if sprites is not None and len(sprites):
            budget -= len(sprites)
            s_colour, s_vis = draw_sprites(sprites, cell, h, w)
            run[3] += s_colour
            run[4] += s_vis
        run[1] += (1.0 - run[1][..., 3:4]) * blurred
        run[2] += vis
        if lit:
            # a layer that may have sprites is a run of its own: the layers behind it must be hidden
            # by its sprites' coverage too, which only the frame's accumulators hold
            end_run()
        if capture is not None:
            capture(index, over + (1.0 - over[..., 3:4]) * (upsample(run[1], layer.scale, h, w) + run[3]) if run else over)
    end_run()
    inner = (slice(guard, h - guard), slice(guard, w - guard))
    return resolve(over, visible)[::-1][inner], acc_depth[::-1][inner]
