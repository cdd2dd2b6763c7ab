"""The deep image of the sliced depth of field (``RenderSettings.dof == "sliced"`` with an aperture):
each blurred layer a sample over its depth range, read from the GPU's own composite.

rendering/sliced.py composites the blurred layers front to back ("over") into the frame's
accumulator, a run of reduced layers first into the run's at its level, upsampled into the frame
once the run ends; slice_resolve.frag then scales the composite up to the layers' summed visible
coverage where cuts between layers left it short. While a deep image is drawn,
:class:`SliceCapture` reads back what each layer wrote (the accumulator it was blended into,
within the box it wrote) and keeps C_j, the frame's "over" after layer j, at every pixel the layer
changed; a reduced layer's is the frame before its run, "over" the run so far upsampled
(slices.upsample's bilinear filter, as slice_upsample.frag): the upsampling is linear, so the run's
last layer gives the frame the GPU composites. The draw is not changed.

The samples telescope through those composites as dofview.deep describes for splats. With F the
resolved pixel (blend space) and k = F.a / A_n (A_n the composite's coverage), the prefixes are
E_j = k·C_j (E_n = F itself), of coverage k·A_j, transmittance T_j = 1 − k·A_j: the resolve's
scale-up spread over the layers as it scales their composite. A sample closing at E_j, opened at
E_i, holds A = 1 − T_j/T_i and RGB = (decode(E_j) − decode(E_i)) / T_i (decode: the identity for a
linear blend): flattening all samples gives decode(F), the flat frame, to float rounding, and the
samples in front of a depth the resolved composite of the layers in front of it.

Depths. A layer's sample spans the camera depths of its Gaussians' centres (the draw order is
sorted by them, so layers follow each other without overlapping; a pixel's light from a layer is
its blurred Gaussians', whatever pixel they are centred on). Consecutive layers of a pixel merge
as splats do (``DeepSettings.tolerance`` on the sample's front depth, at most ``cap`` samples);
a layer that leaves less than :data:`OPEN_MIN` of the light passing closes no sample (nothing
behind it shows: its light goes into the next).
"""

from __future__ import annotations

from collections.abc import Callable

import moderngl
import numpy as np

from dofview.camera import Camera
from dofview.deep import DeepFrame, DeepSettings
from dofview.rendering.depth_order import camera_depths
from dofview.rendering.slices import Box, Layer
from dofview.tonemap import decode

CHANGE_MIN = 1e-7
"""Change of a pixel's composite (any of R, G, B, A) below which a layer adds no sample there (its
light, if any, goes into the pixel's next one)."""
OPEN_MIN = 1e-6
"""Transmittance below which no sample is opened (its colour would be divided by it)."""


def _upsample_window(img: np.ndarray, scale: int, rows: tuple[int, int], cols: tuple[int, int]) -> np.ndarray:
    """Rows ``rows`` and columns ``cols`` (half-open, full-resolution GL pixels) of the bilinear
    upsampling by ``scale`` of ``img`` (h, w, 4) (slices.upsample's filter, slice_upsample.frag)."""
    def taps(lo: int, hi: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        pos = np.clip((np.arange(lo, hi) + 0.5) / scale - 0.5, 0.0, n - 1)
        i0 = np.floor(pos).astype(np.int64)
        return i0, np.minimum(i0 + 1, n - 1), (pos - i0).astype(np.float32)

    y0, y1, fy = taps(*rows, img.shape[0])
    x0, x1, fx = taps(*cols, img.shape[1])
    fy, fx = fy[:, None, None], fx[None, :, None]
    top = img[y0][:, x0] * (1 - fx) + img[y0][:, x1] * fx
    bottom = img[y1][:, x0] * (1 - fx) + img[y1][:, x1] * fx
    return top * (1 - fy) + bottom * fy


def _read(fbo: moderngl.Framebuffer, box: Box) -> np.ndarray:
    """(y1 − y0, x1 − x0, 4) float32 the colour attachment 0 of ``fbo`` in ``box`` (GL pixels, rows up)."""
    x0, y0, x1, y1 = box
    data = fbo.read(viewport=(x0, y0, x1 - x0, y1 - y0), components=4, attachment=0, dtype="f4")
    return np.frombuffer(data, np.float32).reshape(y1 - y0, x1 - x0, 4)


class SliceCapture:
    """What each layer of one sliced draw composited, per pixel (SlicedDof.capture).

    Args:
        width, height: the frame (px).
        guard: the draw's guard band (px on every side of the frame), or what gives it once the
            first layer is composited (SlicedDof sets it as it plans the frame).
    """

    def __init__(self, width: int, height: int, guard: int | Callable[[], int]) -> None:
        self.size, self._guard = (width, height), guard
        self.guard = 0
        self.over: np.ndarray | None = None  # the frame's "over" in the guarded image, GL rows
        self._base: np.ndarray | None = None  # the frame before the current run
        self._run: np.ndarray | None = None  # the current run's accumulator, at its level
        self.pixels: list[np.ndarray] = []  # per captured layer: the frame pixels it changed (row-major, rows down)
        self.layers: list[int] = []  # … its index in the draw's layers
        self.values: list[np.ndarray] = []  # … the frame's composite there after it, (n, 4) blend space

    def layer(self, index: int, fbo: moderngl.Framebuffer, box: Box, scale: int, fresh: bool) -> None:
        """Layer ``index`` was composited into ``fbo`` within ``box`` (its pixels, GL rows): the
        frame's accumulator (``scale`` 1) or its run's at 1/``scale`` (``fresh``: the run's first)."""
        if box[2] <= box[0] or box[3] <= box[1]:
            return
        self._start()
        if scale == 1:
            self.record(index, box, _read(fbo, box))
            return
        if fresh:
            self._base = self.over.copy()
            self._run = np.zeros((fbo.height, fbo.width, 4), np.float32)
        self._run[box[1]:box[3], box[0]:box[2]] = _read(fbo, box)
        # the full-resolution pixels the run's upsampling reads these texels at (one more around)
        gh, gw = self.over.shape[:2]
        region = (max((box[0] - 1) * scale, 0), max((box[1] - 1) * scale, 0),
                  min((box[2] + 1) * scale, gw), min((box[3] + 1) * scale, gh))
        base = self._base[region[1]:region[3], region[0]:region[2]]
        up = _upsample_window(self._run, scale, (region[1], region[3]), (region[0], region[2]))
        self.record(index, region, base + (1.0 - base[..., 3:4]) * up)

    def whole(self, index: int, over: np.ndarray) -> None:
        """Layer ``index`` left the guarded image's "over" at ``over`` (h, w, 4), GL rows (the CPU
        twin: slices.sliced_image's ``capture``)."""
        self._start()
        self.record(index, (0, 0, over.shape[1], over.shape[0]), over)

    def _start(self) -> None:
        if self.over is None:
            w, h = self.size
            self.guard = g = self._guard if isinstance(self._guard, int) else self._guard()
            self.over = np.zeros((h + 2 * g, w + 2 * g, 4), np.float32)

    def record(self, index: int, region: Box, new: np.ndarray) -> None:
        """The guarded image's "over" is ``new`` within ``region`` (GL pixels) after layer ``index``:
        keep it at the frame's pixels it changed."""
        g, (w, h) = self.guard, self.size
        x0, y0 = max(region[0], g), max(region[1], g)
        x1, y1 = min(region[2], g + w), min(region[3], g + h)
        if x1 > x0 and y1 > y0:  # the frame's pixels only: the band is a source of light, not a part of the image
            inner = new[y0 - region[1]:y1 - region[1], x0 - region[0]:x1 - region[0]]
            changed = np.abs(inner - self.over[y0:y1, x0:x1]).max(axis=-1) > CHANGE_MIN
            rows, cols = np.nonzero(changed)
            self.pixels.append((h - 1 - (rows + y0 - g)) * w + (cols + x0 - g))
            self.layers.append(index)
            self.values.append(inner[rows, cols])
        self.over[region[1]:region[3], region[0]:region[2]] = new

    def deep(self, resolved: np.ndarray, depths: np.ndarray, settings: DeepSettings, encoded: bool) -> DeepFrame:
        """The deep image (see the module docstring).

        Args:
            resolved: (H, W, 4) the drawn frame, rows down, in the blend space (the renderer's
                colour target as it holds it).
            depths: (L, 2) per layer of the draw its front and back camera depth (:func:`layer_depths`).
            settings: the merge tolerance and the cap.
            encoded: the layers were blended display-encoded (the samples are decoded).
        """
        w, h = self.size
        if not self.pixels or not sum(len(p) for p in self.pixels):
            return DeepFrame(np.zeros((h, w), np.int64), np.zeros((0, 4)), np.zeros((0, 2)))
        pix = np.concatenate(self.pixels)
        lay = np.concatenate([np.full(len(p), i) for p, i in zip(self.pixels, self.layers)])
        val = np.concatenate(self.values).astype(np.float64)
        order = np.argsort(pix, kind="stable")  # per pixel, front to back (the layers were captured so)
        pix, lay, val = pix[order], lay[order], val[order]
        counts = np.bincount(pix, minlength=w * h)
        start = np.concatenate([[0], np.cumsum(counts)[:-1]])
        have = np.nonzero(counts)[0]
        last = start[have] + counts[have] - 1
        final = resolved.reshape(-1, 4).astype(np.float64)[have]
        cover = val[last, 3]
        k = np.where(cover > 0, final[:, 3] / np.where(cover > 0, cover, 1.0), 1.0)
        val *= np.repeat(k, counts[have])[:, None]
        val[last] = final  # the resolved pixel itself: flattening gives the frame, to float rounding
        trans = np.clip(1.0 - val[:, 3], 0.0, 1.0)
        front, back = depths[lay, 0], depths[lay, 1]

        # which entries close a sample: walked position by position, all pixels at once
        closes = np.zeros(len(pix), bool)
        opened_at = front[start[have]]  # the open sample's front depth, per pixel of ``have``
        closed = np.zeros(len(have), np.int64)
        n = counts[have]
        for i in range(int(n.max())):
            on = np.nonzero(n > i)[0]
            e = start[have[on]] + i
            end = n[on] == i + 1
            nxt = front[np.minimum(e + 1, len(pix) - 1)]
            shut = end | ((trans[e] > OPEN_MIN) & (nxt > opened_at[on] * (1.0 + settings.tolerance))
                          & (closed[on] < settings.cap - 1))
            closes[e] = shut
            closed[on] += shut
            opened_at[on] = np.where(shut, nxt, opened_at[on])
        ends = np.nonzero(closes)[0]
        first_of_pixel = np.r_[True, pix[ends][1:] != pix[ends][:-1]]
        opens = np.where(first_of_pixel, -1, np.r_[-1, ends[:-1]])  # the entry each sample opens after
        colour = val[:, :3] if not encoded else decode(val[:, :3])
        before = np.where(opens[:, None] >= 0, colour[np.maximum(opens, 0)], 0.0)
        t_open = np.where(opens >= 0, trans[np.maximum(opens, 0)], 1.0)
        rgba = np.empty((len(ends), 4))
        rgba[:, :3] = (colour[ends] - before) / t_open[:, None]
        rgba[:, 3] = np.clip(1.0 - trans[ends] / t_open, 0.0, 1.0)
        depth = np.stack([front[np.where(opens >= 0, opens + 1, start[pix[ends]])], back[ends]], 1)
        return DeepFrame(np.bincount(pix[ends], minlength=w * h).reshape(h, w), rgba, depth)


def layer_depths(layers: list[Layer], order: np.ndarray, means: np.ndarray, camera: Camera,
                 near: float) -> np.ndarray:
    """(L, 2) float64 per layer its front and back camera depth: the nearest and farthest centre of
    its Gaussians (``order`` (N,) the draw order the layers cut, ``means`` (N, 3) the scene's), no
    nearer than ``near``, made monotone where an order sorted by quantised keys mixes neighbours,
    so that the layers' ranges follow each other without overlapping."""
    z = np.maximum(camera_depths(means, camera).astype(np.float64), near)[order]
    out = np.array([[z[layer.first:layer.end].min(), z[layer.first:layer.end].max()] if layer.end > layer.first
                    else [near, near] for layer in layers]).reshape(-1, 2)
    out[:, 0] = np.maximum.accumulate(out[:, 0])
    out[:, 1] = np.maximum(out[:, 1], out[:, 0])
    out[:-1, 1] = np.minimum(out[:-1, 1], out[1:, 0])
    return out
