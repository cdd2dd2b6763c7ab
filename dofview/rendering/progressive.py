"""Progressive thin lens: the physical depth of field, refined one pinhole pass at a time.

A thin lens is the average of pinhole images over the lens disk in linear light (accumulate.py).
Here the disk points come from a fixed low-discrepancy sequence (:func:`disk_sequence`), so the
first N are well spread for every N and N samples always give the same image: the viewer adds one
pass per frame while camera and lens rest, and ``dofview render --lens-samples N`` renders the very
image the viewer shows after N still frames. Passes are summed on the GPU in two float targets
(decoded colour, and the depth sums Σw·z, Σw/z, –, Σw), and the average is resolved into the
renderer's own targets, so read() and the display pass serve it like a single-pass frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import moderngl
import numpy as np

from dofview.camera import Camera
from dofview.frame import Frame, RenderSettings
from dofview.lens import Lens
from dofview.rendering.base import Renderer
from dofview.rendering.gl import load_shader

PLASTIC = 1.324717957244746  # the plastic number: the 2D golden ratio of the R2 sequence
SHOW_AFTER = 8
"""Samples from which the viewer shows the accumulation instead of the single-pass image. On the five
real scenes 4 passes come within 0.4 dB of the default single pass (above it on three) and 8 beat
it by 2–7 dB (docs/BENCHMARKS.md, real scenes); fewer show the separate pinhole images as ghosts."""


def disk_sequence(n: int) -> np.ndarray:
    """(n, 2) float64 points of the unit disk: the first n of the R2 low-discrepancy sequence
    (Roberts 2018) mapped area-preservingly (r = √u₁, θ = 2π·u₂). A prefix of the same infinite
    sequence for every n, unlike the sunflower spiral of accumulate.lens_samples."""
    i = np.arange(1, n + 1, dtype=np.float64)[:, None]
    u = np.mod(0.5 + i * np.array([1.0 / PLASTIC, 1.0 / PLASTIC ** 2]), 1.0)
    r, th = np.sqrt(u[:, 0]), 2.0 * math.pi * u[:, 1]
    return np.stack([r * np.cos(th), r * np.sin(th)], axis=1)


def pass_settings(settings: RenderSettings) -> RenderSettings:
    """Settings of the pinhole passes: those of the physical truth (τ = 0, nothing dropped; the
    trained display-encoded blend), whatever the single-pass settings are."""
    return replace(settings, tau=0.0, blend_linear=False)


class ProgressiveLens:
    """Accumulates lens-sampled pinhole passes of ``renderer`` (see the module docstring)."""

    def __init__(self, renderer: Renderer) -> None:
        self.renderer = renderer
        self.ctx = renderer.ctx
        self.samples = 0
        self._program = self.ctx.program(vertex_shader=load_shader("fullscreen.vert"),
                                         fragment_shader=load_shader("progressive.frag"))
        self._vao = self.ctx.vertex_array(self._program, [])
        self._size: tuple[int, int] | None = None
        self._single_encoded = False

    def _targets(self, size: tuple[int, int]) -> None:
        if self._size == size:
            return
        self._release_targets()
        tex = [self.ctx.texture(size, 4, dtype="f4") for _ in range(4)]
        for t in tex:
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._acc, self._single = tex[:2], tex[2:]
        self._acc_fbo = self.ctx.framebuffer(color_attachments=self._acc)
        self._single_fbo = self.ctx.framebuffer(color_attachments=self._single)
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

    def restart(self, keep_single: bool = False) -> None:
        """Forget the samples. ``keep_single``: the renderer's targets hold the single-pass image of
        the new state; keep a copy to show until :data:`SHOW_AFTER` samples are in."""
        self.samples = 0
        if keep_single:
            r = self.renderer
            self._targets((r.colour_tex.width, r.colour_tex.height))
            self._copy((r.colour_tex, r.depth_tex), self._single_fbo, 1.0)
            self._single_encoded = r._encoded

    def add(self, camera: Camera, lens: Lens, settings: RenderSettings, count: int = 1) -> int:
        """Draw and add the next ``count`` pinhole passes (sorted for their own camera, as
        accumulate.py's are); returns the samples so far. Leaves the last pass in the renderer's
        targets: call :meth:`resolve` or :meth:`show` before reading or displaying."""
        r = self.renderer
        self._targets((camera.width, camera.height))
        pts = disk_sequence(self.samples + count)[self.samples:] * (0.5 * lens.diameter(camera.fx))
        pinhole, st = Lens(lens.focus, 0.0), pass_settings(settings)
        for u, v in pts:
            r.draw(camera.lens_shifted(float(u), float(v), lens.focus), pinhole, st)
            if self.samples == 0:
                self._acc_fbo.clear(0.0, 0.0, 0.0, 0.0)
            self._copy((r.colour_tex, r.depth_tex), self._acc_fbo, 1.0, decode=r._encoded, add=True)
            self.samples += 1
        r.camera, r.lens = camera, lens
        return self.samples

    def resolve(self) -> None:
        """Put the average of the samples (linear light) into the renderer's targets."""
        r = self.renderer
        self._copy(tuple(self._acc), r.fbo, 1.0 / self.samples)
        r._encoded = False

    def show(self) -> None:
        """The image the viewer shows into the renderer's targets: the average once
        :data:`SHOW_AFTER` samples are in, the kept single-pass image before."""
        if self.samples >= SHOW_AFTER:
            self.resolve()
        else:
            self._copy(tuple(self._single), self.renderer.fbo, 1.0)
            self.renderer._encoded = self._single_encoded

    def _release_targets(self) -> None:
        if self._size is not None:
            for obj in (self._acc_fbo, self._single_fbo, *self._acc, *self._single):
                obj.release()
        self._size = None

    def release(self) -> None:
        self._release_targets()
        self._vao.release()
        self._program.release()


def render_lens_samples(renderer: Renderer, camera: Camera, lens: Lens, settings: RenderSettings, samples: int,
                        progress: Callable[[int, int], None] | None = None) -> Frame:
    """The thin lens from ``samples`` pinhole passes (the :func:`disk_sequence` points), resolved
    into ``renderer``'s targets (so its display pass shows it) and read back as a linear Frame."""
    if samples < 1:
        raise ValueError("samples must be ≥ 1")
    acc = ProgressiveLens(renderer)
    try:
        for i in range(samples):
            acc.add(camera, lens, settings)
            if progress:
                progress(i + 1, samples)
        acc.resolve()
        return renderer.read()
    finally:
        acc.release()
