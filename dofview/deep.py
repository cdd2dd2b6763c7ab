"""Deep images: per pixel, the list of what lies along its ray, front to back (OpenEXR 2 deep data),
and the settings that bound that list.

A renderer's deep image (:meth:`dofview.rendering.Renderer.deep`) holds each pixel's splats as
samples: contributions whose camera depths lie within a relative ``tolerance`` of the first one of a
sample are merged into it ("over" within the merge), and a pixel keeps at most ``cap`` samples (the
last one takes everything behind it). A compositor merges other deep images in between (a CG
element held out by the splats in front of it and holding out those behind), and flattening the
deep image ("over", front to back) gives the flat render back.

Colour space. The samples are linear light, premultiplied, like the flat EXR. A standard 3DGS
scene blends display-encoded colours, and its flat pixel is the decoded blend, decode(E_N) with
E_N = Σ cᵢ·αᵢ·Tᵢ: decoding each splat or each sample on its own would not add up to that (a
power of a sum is not the sum of powers). So sample j, which closes the blend's running sum at
E_j (transmittance T_j, opened at E_{j−1}, T_{j−1}), holds RGB = (decode(E_j) − decode(E_{j−1})) /
T_{j−1} and A = 1 − T_j / T_{j−1}: flattening the samples in front of any depth telescopes to
decode(E_j), the scene's own image of what lies in front of it, and all of them to the flat pixel
(exactly, up to float rounding). What cannot be exact is a foreign element merged *between*
samples of an encoded scene: the scene blends it in the encoded space, a compositor in linear
light; the difference lives in the pixels partly covered in front of the element
(docs/COMPOSITING.md gives it measured). A linear (HDR) scene has no such difference.

The data type is the same whether the samples are splat groups (the pinhole, the per-splat
depth-of-field mode) or the sliced mode's blurred depth layers (rendering/deep_sliced.py): each
layer a sample over its Z … ZBack range, telescoped the same way through the layers' front-to-back
composite (E and T after each layer, in the space the layers are composited in).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from dofview.errors import DofviewError
from dofview.lens import exposure_from_ev

DEFAULT_TOLERANCE = 0.01
"""Relative depth within which a pixel's contributions merge into one sample: chosen in
docs/BENCHMARKS.md ("Deep output")."""
TRANSMITTANCE_MIN = 1e-4
"""A pixel's walk ends where the light still passing falls below this (the compute blend's early stop)."""
DEFAULT_CAP = 64
"""Most samples a pixel keeps (docs/BENCHMARKS.md, "Deep output": the 99th percentile stays far below)."""


@dataclass(frozen=True)
class DeepSettings:
    """How a pixel's contributions become deep samples.

    Attributes:
        tolerance: relative depth: a contribution at camera depth z joins the open sample, whose
            first contribution is at z₀, when z ≤ z₀·(1 + tolerance); > 0.
        cap: most samples per pixel, ≥ 1 (the last one takes all that lies behind it).
    """

    tolerance: float = DEFAULT_TOLERANCE
    cap: int = DEFAULT_CAP

    def __post_init__(self) -> None:
        if not (math.isfinite(self.tolerance) and self.tolerance > 0):
            raise DofviewError(f"--deep-tolerance must be a finite relative depth > 0, got {self.tolerance}")
        if not (isinstance(self.cap, int) and 1 <= self.cap < 2**24):
            raise DofviewError(f"--deep-cap must be a whole number of samples ≥ 1, got {self.cap}")

    def to_dict(self) -> dict[str, object]:
        """The settings by field name (the deep EXR header's ``dofview:deep``)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, d: dict[str, object]) -> "DeepSettings":
        """The settings of :meth:`to_dict` (missing entries: defaults).

        Raises:
            DofviewError: an unknown or malformed entry.
        """
        unknown = [k for k in d if k not in ("tolerance", "cap")]
        if unknown:
            raise DofviewError(f"deep settings: unknown entry {unknown[0]!r}")
        try:
            return cls(float(d.get("tolerance", DEFAULT_TOLERANCE)),  # type: ignore[arg-type]
                       int(d.get("cap", DEFAULT_CAP)))  # type: ignore[call-overload]
        except (TypeError, ValueError) as e:
            raise DofviewError(f"deep settings: malformed entry ({e})") from None

    def to_args(self) -> list[str]:
        """``dofview render`` arguments that give these settings (with ``--deep OUT``)."""
        return ["--deep-tolerance", repr(float(self.tolerance)), "--deep-cap", str(self.cap)]


@dataclass
class DeepFrame:
    """A deep image: each pixel's samples, front to back.

    Attributes:
        counts: (H, W) int64 samples per pixel, rows top to bottom (0: nothing along that ray).
        rgba: (S, 4) float32 each sample's linear RGB premultiplied by its alpha, and the alpha
            (S = counts.sum(); the samples of pixel (0, 0), then (0, 1), …, row by row, each
            pixel's front to back).
        depth: (S, 2) float32 each sample's camera z (scene units, along the viewing axis, as the
            flat EXR's Z) at its front (Z) and back (ZBack); Z = ZBack for a single splat.
        meta: attributes written into the EXR header (as :attr:`dofview.frame.Frame.meta`).
    """

    counts: np.ndarray
    rgba: np.ndarray
    depth: np.ndarray
    meta: dict[str, object] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.counts = np.asarray(self.counts, np.int64)
        self.rgba = np.asarray(self.rgba, np.float32).reshape(-1, 4)
        self.depth = np.asarray(self.depth, np.float32).reshape(-1, 2)
        total = int(self.counts.sum())
        if self.counts.ndim != 2 or (self.counts.size and self.counts.min() < 0):
            raise ValueError(f"counts must be (H, W) ≥ 0, got shape {self.counts.shape}")
        if len(self.rgba) != total or len(self.depth) != total:
            raise ValueError(f"counts hold {total} samples, rgba {len(self.rgba)}, depth {len(self.depth)}")

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W)."""
        return self.counts.shape  # type: ignore[return-value]

    @property
    def samples(self) -> int:
        return len(self.rgba)

    @property
    def offsets(self) -> np.ndarray:
        """(H·W + 1,) int64: pixel p's samples are [offsets[p], offsets[p + 1])."""
        return np.concatenate([[0], np.cumsum(self.counts.ravel())])

    def pixel(self, row: int, col: int) -> tuple[np.ndarray, np.ndarray]:
        """(n, 4) RGBA and (n, 2) Z, ZBack of one pixel's samples (row from the top)."""
        p = row * self.shape[1] + col
        lo, hi = self.offsets[p], self.offsets[p + 1]
        return self.rgba[lo:hi], self.depth[lo:hi]

    def flatten(self) -> np.ndarray:
        """(H, W, 4) float32: each pixel's samples composited front to back ("over"), in the order
        of their front depth Z (then ZBack; samples are taken whole, as a compositor's flatten
        without volumetric splitting): the flat image, linear premultiplied RGBA."""
        ordered = self.sorted()
        h, w = self.shape
        out = np.zeros((h * w, 4), np.float64)
        trans = np.ones(h * w)
        start = ordered.offsets[:-1]
        counts = ordered.counts.ravel()
        for k in range(int(counts.max()) if counts.size else 0):
            px = np.nonzero(counts > k)[0]
            s = ordered.rgba[start[px] + k].astype(np.float64)
            out[px] += trans[px, None] * s
            trans[px] *= 1.0 - s[:, 3]
        return out.reshape(h, w, 4).astype(np.float32)

    def sorted(self) -> "DeepFrame":
        """This image with each pixel's samples ordered by Z, then ZBack (itself when they are)."""
        pix = np.repeat(np.arange(self.counts.size), self.counts.ravel())
        z, back = self.depth[:, 0], self.depth[:, 1]
        same = pix[1:] == pix[:-1]
        step = (z[1:] > z[:-1]) | ((z[1:] == z[:-1]) & (back[1:] >= back[:-1]))
        if np.all(step | ~same):
            return self
        order = np.lexsort((back, z, pix))
        return DeepFrame(self.counts, self.rgba[order], self.depth[order], dict(self.meta))

    def merge(self, other: "DeepFrame") -> "DeepFrame":
        """Both images' samples in one, each pixel's ordered by Z then ZBack (this image's first
        where they tie): a compositor's deep merge (Nuke's DeepMerge, operation "combine")."""
        if other.shape != self.shape:
            raise DofviewError(f"deep merge: images of {self.shape[1]}×{self.shape[0]} and "
                               f"{other.shape[1]}×{other.shape[0]} pixels")
        pix = np.concatenate([np.repeat(np.arange(self.counts.size), self.counts.ravel()),
                              np.repeat(np.arange(other.counts.size), other.counts.ravel())])
        depth = np.concatenate([self.depth, other.depth])
        order = np.lexsort((depth[:, 1], depth[:, 0], pix))
        return DeepFrame(self.counts + other.counts, np.concatenate([self.rgba, other.rgba])[order], depth[order],
                         dict(self.meta))

    def sample_stats(self) -> dict[str, float]:
        """Samples per pixel: mean, 99th percentile and most; and the share of empty pixels."""
        c = self.counts.ravel()
        return {"mean": float(c.mean()), "p99": float(np.percentile(c, 99)), "max": int(c.max()),
                "empty": float((c == 0).mean())}

    def save_deep_exr(self, path: str | Path, *, exposure: float = 0.0) -> None:
        """Write an OpenEXR deep scanline file: channels R, G, B, A (linear, premultiplied, ×
        2^``exposure``, EV stops), Z and ZBack (camera z, scene units), float32, with :attr:`meta`
        in the header; whole or not at all."""
        from dofview.io.exr import write_deep_exr

        gain = np.float32(exposure_from_ev(exposure))
        colour = np.nan_to_num(self.rgba, nan=0.0, posinf=np.finfo(np.float32).max)
        channels = {c: colour[:, i] * (gain if i < 3 else np.float32(1.0)) for i, c in enumerate("RGBA")}
        channels.update(Z=self.depth[:, 0], ZBack=self.depth[:, 1])
        write_deep_exr(path, self.counts, channels, self.meta)

    @classmethod
    def load(cls, path: str | Path) -> "DeepFrame":
        """A deep EXR with R, G, B, A, Z (and ZBack: Z where absent) read back (its header as
        :attr:`meta`; the colour as stored, exposure applied).

        Raises:
            DofviewError: not a readable deep EXR, or a channel missing.
        """
        from dofview.io.exr import read_deep_exr

        counts, ch, header = read_deep_exr(path)
        missing = [c for c in "RGBAZ" if c not in ch]
        if missing:
            raise DofviewError(f"{path}: deep EXR without channel {missing[0]}")
        rgba = np.stack([ch[c] for c in "RGBA"], 1)
        depth = np.stack([ch["Z"], ch.get("ZBack", ch["Z"])], 1)
        return cls(counts, rgba, depth, header)
