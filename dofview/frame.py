"""What a render produces: linear RGBA and depth, plus the settings every renderer shares."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from dofview.errors import DofviewError
from dofview.lens import exposure_from_ev
from dofview.tonemap import Tonemap, display, to_uint8

OPACITY_NORMS: tuple[str, ...] = ("none", "energy", "optical-depth")
CUT_MODES: tuple[str, ...] = ("drop", "conserve")
KERNELS: tuple[str, ...] = ("gaussian", "disk")
DOF_MODES: tuple[str, ...] = ("splat", "sliced")


BLADES_MAX = 64  # aperture blades of the sliced mode: 0 (a disk) or 3…BLADES_MAX


@dataclass(frozen=True)
class RenderSettings:
    """Splatting settings shared by the GL renderer and the CPU reference.

    Attributes:
        tau: minimum per-pixel alpha τ in [0, 1); contributions below it are dropped. A Gaussian's
            support is its 3σ ellipse, cut further to where α ≥ τ.
        k: aperture covariance scale: Σ₂′ = Σ₂ + k·R²·I (R the CoC radius, pixels).
        opacity_norm: "energy" (o′ = o·β, β = sqrt(det Σ₂ / det Σ₂′), Eq. 5), "optical-depth"
            (−ln(1−o′) = β·(−ln(1−o))) or "none".
        blend_linear: decode each splat's colour to linear light before blending (only changes
            display-encoded scenes).
        near: near plane, camera z in scene units; Gaussians with z ≤ near are not drawn.
        cut: how τ cuts a splat (lens.cut_splat): "drop" draws o′ where α ≥ τ and culls splats below
            τ everywhere (the light of wide, faint blurred splats is lost); "conserve" draws o′ + τ
            inside the ellipse where that falls to τ, which keeps each splat's whole mass (better
            where the lost light dominates the error, worse where blurred stacks over-cover).
        kernel: the aperture kernel a splat is blurred with (lens.kernel_shape): "gaussian" (Σ₂ + k·R²·I)
            or "disk" (the same ellipse with the radial profile of a Gaussian spread over a disk of
            radius 2·sqrt(k)·R, the thin lens's circle of confusion at k = 1/4); "disk" works with the
            "drop" cut only.
        dof: how depth of field is made: "sliced" (the default) blends depth slices as a pinhole
            and blurs each with the aperture (rendering/sliced.py; k, the kernel, the opacity
            normalisation and the cut then apply only to its front and back layers, the splats
            blurred beyond SliceRule.huge of the frame); "splat" blurs each
            splat (k, the kernel, the opacity normalisation), the published single pass.
        blades: aperture of the sliced mode: 0 a disk, n ≥ 3 a regular n-gon.
        blade_rotation: the polygon's first corner, degrees from +x (image right).
    """

    tau: float = 1.0 / 255.0  # chosen by docs/BENCHMARKS.md "Speed against error"
    k: float = 0.25
    opacity_norm: str = "energy"
    blend_linear: bool = False
    near: float = 0.01
    cut: str = "drop"  # "conserve" wins on one real scene of five: docs/BENCHMARKS.md, real scenes
    kernel: str = "gaussian"  # "disk": docs/BENCHMARKS.md, "A disk-shaped kernel"
    dof: str = "sliced"  # docs/BENCHMARKS.md, "Sliced depth of field"
    blades: int = 0
    blade_rotation: float = 0.0

    def __post_init__(self) -> None:
        if not (0.0 <= self.tau < 1.0):
            raise DofviewError(f"tau (minimum alpha) must be in [0, 1), got {self.tau}")
        if not (math.isfinite(self.k) and self.k >= 0):
            raise DofviewError(f"k (aperture covariance scale) must be finite and ≥ 0, got {self.k}")
        if self.opacity_norm not in OPACITY_NORMS:
            raise DofviewError(f"opacity normalisation must be one of {', '.join(OPACITY_NORMS)}")
        if self.cut not in CUT_MODES:
            raise DofviewError(f"tau cut must be one of {', '.join(CUT_MODES)}, got {self.cut!r}")
        if self.kernel not in KERNELS:
            raise DofviewError(f"kernel must be one of {', '.join(KERNELS)}, got {self.kernel!r}")
        if self.kernel == "disk" and self.cut != "drop":
            raise DofviewError("the disk kernel works with the drop cut only (--cut drop)")
        if not (math.isfinite(self.near) and self.near > 0):
            raise DofviewError(f"near plane must be finite and > 0, got {self.near}")
        if self.dof not in DOF_MODES:
            raise DofviewError(f"depth of field mode must be one of {', '.join(DOF_MODES)}, got {self.dof!r}")
        if self.blades != 0 and not (3 <= self.blades <= BLADES_MAX):
            raise DofviewError(f"aperture blades must be 0 (a disk) or 3…{BLADES_MAX}, got {self.blades}")
        if not math.isfinite(self.blade_rotation):
            raise DofviewError(f"blade rotation must be a finite number of degrees, got {self.blade_rotation}")

    def to_dict(self) -> dict[str, object]:
        """Every setting by its field name (the EXR header's ``dofview:render``, the bench's columns)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, d: dict[str, object]) -> "RenderSettings":
        """The settings of :meth:`to_dict`; a missing entry takes its default (headers written
        before ``near`` was recorded), but a missing ``dof`` is "splat": the one mode of the
        headers written before it was recorded.

        Raises:
            DofviewError: an unknown entry, or a value out of range, named.
        """
        names = {f.name: f for f in fields(cls)}
        unknown = [k for k in d if k not in names]
        if unknown:
            raise DofviewError(f"render settings: unknown entry {unknown[0]!r}")
        cast = {"float": float, "bool": bool, "str": str, "int": int}  # the fields' annotations, as text
        given = {"dof": "splat", **d}
        return cls(**{k: cast[names[k].type](v) for k, v in given.items()})  # type: ignore[index]

    def to_args(self) -> list[str]:
        """``dofview render`` arguments that give these settings (full float precision)."""
        args = ["--tau", repr(float(self.tau)), "--k", repr(float(self.k)), "--opacity-norm", self.opacity_norm,
                "--cut", self.cut, "--kernel", self.kernel, "--near", repr(float(self.near))]
        if self.dof != "sliced":
            args += ["--dof", self.dof]
        if self.blades:
            args += ["--blades", str(self.blades), "--blade-rotation", repr(float(self.blade_rotation))]
        return args + (["--blend-linear"] if self.blend_linear else [])


@dataclass
class Frame:
    """A rendered image.

    Attributes:
        rgba: (H, W, 4) float32 linear RGB premultiplied by alpha (over black), alpha = coverage.
        depth: (H, W) float32 α-weighted mean camera z of the splats, scene units; 0 where α = 0.
        encoded: True when the scene blends display-encoded colours (standard sRGB 3DGS).
        focus_depth: (H, W) float32 1 / (α-weighted mean of 1/z), scene units, 0 where α = 0, or
            None. The CoC is linear in 1/z, so this is the focus that makes a pixel sharpest in the
            least-squares sense, and a far background seen through gaps barely pulls it (the mean
            depth is pulled by its full distance). Focusing uses it when present.
        meta: attributes written into the EXR header (camera, lens, settings; see api.exr_header).
    """

    rgba: np.ndarray
    depth: np.ndarray
    encoded: bool
    focus_depth: np.ndarray | None = None
    meta: dict[str, object] = field(default_factory=dict)

    @property
    def focus_depths(self) -> np.ndarray:
        """(H, W) the depth to focus by: :attr:`focus_depth` where the renderer gave it, else
        :attr:`depth`."""
        return self.depth if self.focus_depth is None else self.focus_depth

    @property
    def alpha(self) -> np.ndarray:
        return self.rgba[..., 3]

    def display(self, tm: Tonemap | None = None) -> np.ndarray:
        """(H, W, 3) uint8 display image."""
        return to_uint8(display(self.rgba, self.encoded, tm or Tonemap(), depth=self.depth))

    def save_exr(self, path: str | Path, *, exposure: float = 0.0, half: bool = False) -> None:
        """Write R, G, B, A (linear, premultiplied, × 2^``exposure``, EV stops; float32 or half) and
        Z (float32) with :attr:`meta` in the header; whole or not at all."""
        from dofview.io.exr import write_exr

        rgba = self.rgba.copy()
        rgba[..., :3] *= exposure_from_ev(exposure)
        write_exr(path, rgba, self.depth, half=half, header=self.meta)

    def save_png(self, path: str | Path, tm: Tonemap | None = None) -> None:
        """Write the display image (tone mapped with ``tm``, default 0 EV, γ 2.2) as an 8-bit PNG."""
        from dofview.io.png import write_png

        write_png(path, self.display(tm))


def depth_from_weighted(weighted: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Σ α_i T_i z_i and coverage → (H, W) float32 mean depth; 0 where nothing was drawn."""
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.where(alpha > 1e-6, weighted / np.maximum(alpha, 1e-6), 0.0)
    return np.nan_to_num(d, nan=0.0, posinf=0.0, neginf=0.0).astype(np.float32)
