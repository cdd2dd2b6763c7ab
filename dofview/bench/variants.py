"""What a bench run varies and what it measures against: the configuration, the single-pass
settings studied, and the thin-lens accumulation references with the error of a frame against them."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from dofview.bench.metrics import log_radiance_error, psnr, ssim
from dofview.camera import Camera
from dofview.frame import OPACITY_NORMS, Frame, RenderSettings
from dofview.lens import BlurSpec, Lens
from dofview.rendering import Renderer
from dofview.rendering.accumulate import accumulate
from dofview.tonemap import Tonemap, decode, display, encode


# ---- what one run measures ---------------------------------------------------------------------
@dataclass(frozen=True)
class BenchConfig:
    """Everything a run varies. Apertures A are px·scene unit at the bench's image width.

    ``apertures`` None: the apertures whose blur is each of ``blur`` (``--blur``, as render's, in px
    of the bench's image): by default the largest blur in view, the CoC radius at the 2nd/98th depth
    percentile of the first view's pinhole image for its first focus, so that a scene gets the same
    blur in pixels whatever its units. ``grid_apertures`` None: 0 and the study's apertures. The
    defaults are sized to finish in minutes on llvmpipe with 2 cores (times: docs/BENCHMARKS.md)."""

    focus: tuple[float | str, ...] = ("auto",)
    blur: tuple[BlurSpec, ...] = (BlurSpec(4.0), BlurSpec(8.0), BlurSpec(16.0))
    apertures: tuple[float, ...] | None = None      # error study
    grid_apertures: tuple[float, ...] | None = None  # the poster's table
    taus: tuple[float, ...] = (0.0, 1 / 255, 2 / 255, 3 / 255)
    ks: tuple[float, ...] = (1 / 9, 1 / 4, 1.0)
    norms: tuple[str, ...] = OPACITY_NORMS
    ref_samples: int = 64
    acc_samples: tuple[int, ...] = (2, 4, 8, 16)
    frames: int = 5
    warmup: int = 1
    counts: tuple[int, ...] = (10_000, 50_000, 200_000)
    count_size: tuple[int, int] = (480, 270)
    widths: tuple[int, ...] = (160, 320, 640)
    scaling_aperture: float = 100.0  # the random scenes' (synth.benchmark_camera's fixed units)
    scaling_frames: int = 2
    raster: str = "auto"  # renderer backend (dofview.rendering.BACKENDS, or "auto")

    def with_apertures(self, width: int, focus: float, span: tuple[float, float]) -> "BenchConfig":
        """This configuration with the apertures it leaves to the scene chosen for a view ``width``
        px wide whose depths in view span ``span`` = (near, far) (scene units) at focus ``focus``."""
        aps = self.apertures or tuple(b.aperture(width, width, focus, span) for b in self.blur)
        return replace(self, apertures=aps, grid_apertures=self.grid_apertures or (0.0, *aps))


QUICK = dict(blur=(BlurSpec(8.0),), taus=(0.0, 2 / 255), ks=(1 / 4, 1.0),
             norms=("energy", "optical-depth"), ref_samples=64, acc_samples=(2, 4, 16), frames=2,
             counts=(2_000, 6_000), count_size=(160, 90), widths=(48, 96), scaling_aperture=40.0,
             scaling_frames=2)
"""--quick: a run of seconds on a tiny image, for the test suite (the reference uses 64 samples)."""


@dataclass(frozen=True)
class Job:
    """One single-pass render to time: a camera, a lens and the splatting settings."""

    view: int
    focus: float
    aperture: float
    settings: RenderSettings


def settings_variants(base: RenderSettings, cfg: BenchConfig, encoded: bool) -> list[RenderSettings]:
    """The single-pass settings studied at each aperture: the base (the default mode, sliced), and
    of the per-splat mode k × opacity normalisation at the base τ, each τ at the base k and
    normalisation, and linear blending (display-encoded scenes only)."""
    splat = replace(base, dof="splat")
    out = [replace(splat, k=k, opacity_norm=n) for k in cfg.ks for n in cfg.norms]
    out += [replace(splat, tau=t) for t in cfg.taus]
    if encoded:
        out.append(replace(splat, blend_linear=not base.blend_linear))
    return list(dict.fromkeys([base, splat] + out))


# ---- references and error ------------------------------------------------------------------------
@dataclass
class References:
    """Thin-lens accumulation references of one camera and lens, linear RGBA frames.

    physical: linear average of the trained pinhole images (light adds on a sensor).
    encoded: average of the display-encoded pinhole images, decoded after: what display-encoded
        single-pass blending approximates (encoded scenes only; else the physical one).
    linear_blend: physical average of pinhole images blended in linear light (blend_linear).
    """

    physical: Frame
    encoded: Frame
    linear_blend: Frame | None


def pinhole_settings(base: RenderSettings, blend_linear: bool = False) -> RenderSettings:
    """Settings of the reference's pinhole renders: τ = 0 (nothing dropped), one splatting pass (at
    aperture 0 the sliced mode is that pass, with more work); k and the opacity normalisation do
    nothing at aperture 0."""
    return replace(base, tau=0.0, blend_linear=blend_linear, dof="splat")


def make_references(renderer: Renderer, camera: Camera, lens: Lens, base: RenderSettings, samples: int,
                    blend_variant: bool, tick: Callable[[], None]) -> References:
    """Accumulate ``samples`` pinhole renders (GL renderer, aperture 0) over the lens disk."""
    pin = Lens(lens.focus, 0.0)
    st = pinhole_settings(base)
    encoded_sum: list[np.ndarray] = []

    def render(cam: Camera) -> Frame:
        f = renderer.render(cam, pin, st)
        enc = encode(f.rgba[..., :3]) if f.encoded else f.rgba[..., :3]
        if encoded_sum:
            encoded_sum[0] += enc
        else:
            encoded_sum.append(enc.astype(np.float64))
        tick()
        return f

    physical = accumulate(render, camera, lens, samples)
    enc_rgba = physical.rgba.copy()
    enc_avg = encoded_sum[0] / samples
    enc_rgba[..., :3] = decode(enc_avg) if physical.encoded else enc_avg
    encoded = Frame(rgba=enc_rgba.astype(np.float32), depth=physical.depth, encoded=physical.encoded)
    linear_blend = None
    if blend_variant:
        st_lin = pinhole_settings(base, blend_linear=True)

        def render_lin(cam: Camera) -> Frame:
            tick()
            return renderer.render(cam, pin, st_lin)

        linear_blend = accumulate(render_lin, camera, lens, samples)
    return References(physical=physical, encoded=encoded, linear_blend=linear_blend)


def errors(frame: Frame, ref: Frame, tm: Tonemap, hdr: bool) -> dict[str, float]:
    """PSNR and SSIM of the display images, and (HDR scenes) the log-radiance error in stops."""
    a = display(frame.rgba, frame.encoded, tm)
    b = display(ref.rgba, ref.encoded, tm)
    out = {"psnr": psnr(a, b), "ssim": ssim(a, b)}
    out["log_radiance"] = log_radiance_error(frame.rgba, ref.rgba) if hdr else float("nan")
    return out
