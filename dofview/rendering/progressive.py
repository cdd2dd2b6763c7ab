"""Progressive thin lens: depth of field refined in stages, each a complete image without ghosts.

A thin lens is the average of pinhole images over the lens disk in linear light (accumulate.py).
Averaging a few pinhole passes shows each one as a sharp ghost of the others, so here the N passes of
a stage each see the scene through their own share of the lens. In the sliced mode (the default)
the lens is cut into N cells (:func:`lens_cells`): pass i is the camera moved to cell i's centroid
and blurred by the cell's own shape at each pixel's CoC (slices.LensCell), weighed by its share, so
the passes add up to the whole lens exactly. In the per-splat mode, which has no kernel shape, pass
i is seen from lens point p_i (:func:`stage_points`) with the single-pass depth of field of the
sub-aperture A/√N (:func:`sub_lens`, the CoC of a disk of 1/N of the lens's area). N = 1 is the
single pass itself; every N is a complete depth-of-field image; as N grows the cells shrink to
points and the stage becomes the accumulation buffer, the exact lens. The viewer refines in stages N = 1, 2, 4, 8, … (:func:`next_stage`) and keeps showing the last
complete stage while the next one accumulates, one pass per still frame; ``dofview render
--lens-samples N`` renders stage N alone, the very image the viewer shows once it reached N.
Passes are summed on the GPU in two float targets (decoded colour, and the depth sums Σw·z, Σw/z,
–, Σw), and the stage shown is put into the renderer's own targets (``Renderer.fill_targets``), so
read() and the display pass serve it like a single-pass frame.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import replace

import moderngl
import numpy as np

from dofview.camera import Camera
from dofview.frame import Frame, RenderSettings
from dofview.lens import Lens
from dofview.rendering.accumulate import lens_samples
from dofview.rendering.base import Renderer
from dofview.rendering.gl import load_shader
from dofview.rendering.slices import Aperture, LensCell

SPREAD = 1.0
"""RMS radius of a stage's lens points over the one that gives the stage the lens's second moment
(see :func:`stage_points`); measured in docs/BENCHMARKS.md, "Lens refinement without ghosts"."""


LAYOUTS = ("cvt", "sunflower")
CVT_MAX = 64
"""Largest stage laid out as a centroidal Voronoi tessellation (its Lloyd iterations take a fraction
of a second at 64 and grow as n²); larger ones, whose sub-apertures are R/8 or less, use the
sunflower (the two were compared at N = 4 and 8 only)."""


@functools.lru_cache(maxsize=32)
def _cvt(n: int, iterations: int = 30) -> np.ndarray:
    """(n, 2) centroids of a centroidal Voronoi tessellation of the unit disk (Lloyd's algorithm on
    32 sunflower samples per cell, from the sunflower points): n cells of equal share, each point at
    the centre of its own."""
    samples = lens_samples(32 * n)
    p = lens_samples(n)
    for _ in range(iterations):
        # nearest point per sample from |s|² − 2 s·p + |p|² (the |s|² term does not change the argmin)
        cell = np.argmin(np.sum(p * p, axis=1)[None, :] - 2.0 * samples @ p.T, axis=1)
        count = np.maximum(np.bincount(cell, minlength=n), 1)
        p = np.stack([np.bincount(cell, samples[:, a], minlength=n) for a in (0, 1)], axis=1) / count[:, None]
    return p


def stage_points(n: int, spread: float = SPREAD, layout: str = "cvt") -> np.ndarray:
    """(n, 2) float64 lens points of a stage of n passes, in units of the lens radius, each the
    centre of its 1/n share of the lens: the centroids of a centroidal Voronoi tessellation of the
    disk (layout "cvt", up to :data:`CVT_MAX`) or Vogel's sunflower (accumulate.lens_samples).
    Moved so that the centroid is the lens centre (else the stage shifts out-of-focus content) and
    scaled so that the points' second moment plus that of a sub-aperture disk (radius 1/√n) is the
    whole disk's: mean |p|² = spread²·(1 − 1/n)/2. n = 1 is the lens centre."""
    if n < 1:
        raise ValueError("a stage has ≥ 1 pass")
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {', '.join(LAYOUTS)}, got {layout!r}")
    p = _cvt(n).copy() if layout == "cvt" and n <= CVT_MAX else lens_samples(n)
    p -= p.mean(axis=0)
    ms = float(np.mean(np.sum(p * p, axis=1)))
    return p * (spread * math.sqrt((1.0 - 1.0 / n) / 2.0 / ms)) if ms > 0 else p


CELL_GRID = 512
"""Samples across the lens's diameter that measure each lens cell (its share, centroid, neighbours
and reach): a 512 × 512 grid, ≈ 206k points on the disk."""
CELL_CHUNK = 16384
"""Samples whose distances to the generators are held at once."""


@functools.lru_cache(maxsize=32)
def lens_cells(n: int, blades: int = 0, rotation: float = 0.0) -> tuple[LensCell, ...]:
    """The sliced mode's stage of ``n`` passes: the aperture (a disk, or ``blades`` ≥ 3 corners,
    the first ``rotation`` radians from +x) cut into the Voronoi cells of n generators (the CVT of
    the disk up to :data:`CVT_MAX`, the sunflower beyond), each cell a pass seen from its centroid
    and blurred by its own shape (slices.LensCell), weighed by its share of the lens: the passes
    add up to the whole lens exactly, so every stage is a complete depth-of-field image, from the
    single pass (n = 1: the whole aperture) to the accumulation buffer (n → ∞). A generator whose
    cell misses a polygon aperture has no pass."""
    aperture = Aperture(blades, rotation)
    if n == 1:
        return (aperture.whole(),)
    gen = _cvt(n) if n <= CVT_MAX else lens_samples(n)
    step = 2.0 / CELL_GRID
    g = (np.arange(CELL_GRID) + 0.5) * step - 1.0
    u = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    u = u[aperture.inside(u)]
    # each sample's nearest and second-nearest generator, in chunks (all at once would hold
    # samples × n distances: 420 MB at n = 256)
    own, second = np.empty(len(u), np.int64), np.empty(len(u), np.int64)
    sq = np.sum(gen * gen, axis=1)
    for s in range(0, len(u), CELL_CHUNK):
        dist = sq[None, :] - 2.0 * u[s:s + CELL_CHUNK] @ gen.T  # |u − g|² less |u|²: the same order
        two = np.argpartition(dist, 1, axis=1)[:, :2]
        near = np.take_along_axis(dist, two, 1).argmin(axis=1)
        rows = np.arange(len(two))
        own[s:s + CELL_CHUNK], second[s:s + CELL_CHUNK] = two[rows, near], two[rows, 1 - near]
    # the samples grouped by cell: shares, centroids, reaches and neighbours in one pass each
    count = np.bincount(own, minlength=len(gen))
    centroid = np.stack([np.bincount(own, u[:, k], len(gen)) for k in (0, 1)], 1) / np.maximum(count, 1)[:, None]
    far = np.zeros(len(gen))
    np.maximum.at(far, own, np.hypot(*(u - centroid[own]).T))
    pairs = np.unique(own * len(gen) + second)
    cells = []
    for i in np.flatnonzero(count):
        other = gen[pairs[pairs // len(gen) == i] % len(gen)]  # the neighbours: their bisectors
        normal = (other - gen[i]) / np.hypot(*(other - gen[i]).T)[:, None]
        planes = np.c_[normal, np.sum(normal * (0.5 * (gen[i] + other)), 1)]
        cells.append(LensCell(np.concatenate([planes, aperture.planes().reshape(-1, 3)]), not blades,
                              centroid[i], float(count[i] / len(u)), float(far[i]) + step))
    total = sum(c.share for c in cells)
    return tuple(replace(c, share=c.share / total) for c in cells)


def sub_lens(lens: Lens, n: int) -> Lens:
    """The lens of one pass of an n-pass stage: the same focus, the aperture of 1/n of the lens's
    area (strength A/√n, so the CoC radius R/√n)."""
    return Lens(lens.focus, lens.aperture / math.sqrt(n))


def next_stage(n: int, most: int) -> int:
    """The stage after the one of n passes, in a refinement up to ``most`` passes: twice n, capped."""
    return min(2 * n, most)


def pass_settings(settings: RenderSettings) -> RenderSettings:
    """Settings of the pinhole passes of the pinhole-average refinement (the benchmark's comparison):
    those of the physical truth (τ = 0, nothing dropped; the trained display-encoded blend)."""
    return replace(settings, tau=0.0, blend_linear=False)


class ProgressiveLens:
    """Refines the depth of field of ``renderer`` in stages (see the module docstring).

    ``samples`` is the number of passes of the stage shown (1: the single pass; 0: none kept)."""

    def __init__(self, renderer: Renderer, spread: float = SPREAD, layout: str = "cvt") -> None:
        self.renderer = renderer
        self.ctx = renderer.ctx
        self.spread, self.layout = spread, layout
        self.samples = 0
        self._stage = 0  # passes of the stage in progress, and how many of them are in
        self._done = 0
        self._program = self.ctx.program(vertex_shader=load_shader("fullscreen.vert"),
                                         fragment_shader=load_shader("progressive.frag"))
        self._vao = self.ctx.vertex_array(self._program, [])
        self._size: tuple[int, int] | None = None
        self._shown_encoded = False
        self._view: tuple[Camera, Lens] | None = None  # the camera and lens the stages are of

    def _targets(self, size: tuple[int, int]) -> None:
        if self._size == size:
            return
        self._release_targets()
        tex = [self.ctx.texture(size, 4, dtype="f4") for _ in range(4)]
        for t in tex:
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._acc, self._shown = tex[:2], tex[2:]
        self._acc_fbo = self.ctx.framebuffer(color_attachments=self._acc)
        self._shown_fbo = self.ctx.framebuffer(color_attachments=self._shown)
        self._size = size

    def _copy(self, src: tuple[moderngl.Texture, moderngl.Texture], dst: moderngl.Framebuffer, scale: float,
              decode: bool = False, add: bool = False) -> None:
        src[0].use(0)
        src[1].use(1)
        p = self._program
        p["u_colour"].value = 0
        p["u_depth"].value = 1
        p["u_decode"].value = decode
        p["u_scale"].value = scale
        dst.use()
        self.ctx.viewport = (0, 0, *self._size)
        if add:
            self.ctx.enable(moderngl.BLEND)
            self.ctx.blend_func = moderngl.ONE, moderngl.ONE
            self.ctx.blend_equation = moderngl.FUNC_ADD
        else:
            self.ctx.disable(moderngl.BLEND)
        self._vao.render(moderngl.TRIANGLES, vertices=3)
        self.ctx.disable(moderngl.BLEND)

    def _keep_targets(self) -> None:
        """The renderer's targets (a single pass, as drawn) become the stage shown, N = 1."""
        r = self.renderer
        self._targets((r.colour_tex.width, r.colour_tex.height))
        self._copy((r.colour_tex, r.depth_tex), self._shown_fbo, 1.0)
        self._shown_encoded = r.targets_encoded
        self._view = r.camera, r.lens
        self.samples = 1

    def restart(self, keep_single: bool = False) -> None:
        """Forget the stages. ``keep_single``: the renderer's targets hold the single-pass image of
        the new state; keep it as stage 1, shown until stage 2 is complete."""
        self.samples = self._stage = self._done = 0
        if keep_single:
            self._keep_targets()

    def add(self, camera: Camera, lens: Lens, settings: RenderSettings, stage: int) -> int:
        """Draw the next pass of the ``stage``-pass image (starting it afresh unless it is the stage
        in progress); once its last pass is in it becomes the stage shown. Returns the passes of the
        stage shown. Leaves the pass in the renderer's targets: call :meth:`show` before reading or
        displaying."""
        if stage < 1:
            raise ValueError("a stage has ≥ 1 pass")
        r = self.renderer
        if stage == 1:  # the single pass itself, kept bit for bit
            r.draw(camera, lens, settings)
            self._keep_targets()
            return self.samples
        self._targets((camera.width, camera.height))
        if stage != self._stage:
            self._stage, self._done = stage, 0
        radius = 0.5 * lens.diameter(camera.fx)
        if settings.dof == "sliced":  # the stage's lens cells, each blurred by its own shape
            cells = lens_cells(stage, settings.blades, math.radians(settings.blade_rotation))
            cell = cells[self._done]
            u, v = cell.point * radius
            r.draw(camera.lens_shifted(float(u), float(v), lens.focus), lens, settings, cell=cell)
            weight, passes = cell.share, len(cells)
        else:  # per-splat: points spread over the lens, each blurred by a disk of its share
            u, v = stage_points(stage, self.spread, self.layout)[self._done] * radius
            r.draw(camera.lens_shifted(float(u), float(v), lens.focus), sub_lens(lens, stage), settings)
            weight, passes = 1.0 / stage, stage
        if self._done == 0:
            self._acc_fbo.clear(0.0, 0.0, 0.0, 0.0)
        self._copy((r.colour_tex, r.depth_tex), self._acc_fbo, weight, decode=r.targets_encoded, add=True)
        self._done += 1
        if self._done == passes:  # complete: the weighted average, linear light, is the stage shown
            self._copy(tuple(self._acc), self._shown_fbo, 1.0)
            self._shown_encoded = False
            self._view = camera, lens
            self.samples, self._stage, self._done = stage, 0, 0
        return self.samples

    def show(self) -> None:
        """Put the stage shown into the renderer's targets."""
        if not self.samples:
            raise RuntimeError("no stage complete yet")
        self.renderer.fill_targets(lambda fbo: self._copy(tuple(self._shown), fbo, 1.0), self._shown_encoded,
                                   *self._view)

    def _release_targets(self) -> None:
        if self._size is not None:
            for obj in (self._acc_fbo, self._shown_fbo, *self._acc, *self._shown):
                obj.release()
        self._size = None

    def release(self) -> None:
        self._release_targets()
        self._vao.release()
        self._program.release()


def render_lens_samples(renderer: Renderer, camera: Camera, lens: Lens, settings: RenderSettings, samples: int,
                        progress: Callable[[int, int], None] | None = None, spread: float = SPREAD,
                        layout: str = "cvt") -> Frame:
    """The stage of ``samples`` sub-aperture passes (1: the single pass), put into ``renderer``'s
    targets (so its display pass shows it) and read back as a linear Frame: what the viewer shows
    once its refinement reached ``samples``. ``spread``, ``layout``: the lens points' (stage_points)."""
    if samples < 1:
        raise ValueError("samples must be ≥ 1")
    acc = ProgressiveLens(renderer, spread, layout)
    try:
        done = 0
        while acc.add(camera, lens, settings, samples) != samples:  # a stage may have fewer passes (lens_cells)
            done += 1
            if progress:
                progress(done, samples)
        if progress:
            progress(samples, samples)
        acc.show()
        return renderer.read()
    finally:
        acc.release()
