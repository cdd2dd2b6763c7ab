"""Progressive thin lens: depth of field refined in stages, each a complete image without ghosts.

A thin lens is the average of pinhole images over the lens disk in linear light (accumulate.py).
Averaging a few pinhole passes shows each one as a sharp ghost of the others, so here the N passes of
a stage each see the scene through their own share of the lens: pass i is the camera moved to lens
point p_i (:func:`stage_points`) and drawn with the single-pass depth of field of the sub-aperture
A/√N (:func:`sub_lens`, the CoC of a disk of 1/N of the lens's area), with whatever settings the
single pass has. N = 1 is the single pass itself; every N is a complete depth-of-field image; as N
grows the sub-apertures shrink to points and the stage becomes the accumulation buffer, the exact
lens. The viewer refines in stages N = 1, 2, 4, 8, … (:func:`next_stage`) and keeps showing the last
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
        u, v = stage_points(stage, self.spread, self.layout)[self._done] * (0.5 * lens.diameter(camera.fx))
        r.draw(camera.lens_shifted(float(u), float(v), lens.focus), sub_lens(lens, stage), settings)
        if self._done == 0:
            self._acc_fbo.clear(0.0, 0.0, 0.0, 0.0)
        self._copy((r.colour_tex, r.depth_tex), self._acc_fbo, 1.0, decode=r.targets_encoded, add=True)
        self._done += 1
        if self._done == stage:  # complete: the average, linear light, is the stage shown
            self._copy(tuple(self._acc), self._shown_fbo, 1.0 / stage)
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
        for i in range(samples):
            acc.add(camera, lens, settings, samples)
            if progress:
                progress(i + 1, samples)
        acc.show()
        return renderer.read()
    finally:
        acc.release()
