"""The Gaussian scene: activated parameters of a trained 3DGS model, in scene units.

Data flows file → scene → camera + lens → renderer → image. A scene holds only what its file
had: a degree-0 scene has ``sh_rest is None`` and no SH-rest storage anywhere downstream.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

SH_C0 = 0.28209479177387814
ColourSpace = Literal["srgb", "linear"]
COLOUR_SPACES: tuple[str, ...] = ("srgb", "linear")
VISIBLE_OPACITY = 1.0 / 255.0
"""The least opacity at which a Gaussian alone moves an 8-bit pixel by one level (and the default
τ keeps it): a scene with none this opaque draws an empty image."""


def sh_coeff_count(degree: int) -> int:
    """Coefficients per colour channel for SH degree ``degree`` (1, 4, 9, 16)."""
    return (degree + 1) ** 2


@dataclass
class GaussianScene:
    """A set of 3D Gaussians with activated parameters.

    Attributes:
        means: (N, 3) float32, scene units, world space.
        quats: (N, 4) float32, unit quaternions (w, x, y, z), world-from-local rotation.
        scales: (N, 3) float32, scene units, standard deviations along the local axes (> 0).
        opacities: (N,) float32 in [0, 1] (sigmoid of the stored logit).
        sh_dc: (N, 3) float32, the degree-0 SH coefficient per channel (colour = SH_C0·dc + 0.5).
        sh_rest: (N, K-1, 3) float32 with K = (degree+1)², or None for degree 0.
        colour_space: "srgb" when the blended values are display-encoded (standard 3DGS fit to
            sRGB photos), "linear" when they are linear radiance (HDR training).
    """

    means: np.ndarray
    quats: np.ndarray
    scales: np.ndarray
    opacities: np.ndarray
    sh_dc: np.ndarray
    sh_rest: np.ndarray | None = None
    colour_space: ColourSpace = "srgb"
    name: str = field(default="scene")

    def __post_init__(self) -> None:
        self.means = np.ascontiguousarray(self.means, dtype=np.float32).reshape(-1, 3)
        n = self.means.shape[0]
        self.quats = np.ascontiguousarray(self.quats, dtype=np.float32).reshape(n, 4)
        self.scales = np.ascontiguousarray(self.scales, dtype=np.float32).reshape(n, 3)
        self.opacities = np.ascontiguousarray(self.opacities, dtype=np.float32).reshape(n)
        self.sh_dc = np.ascontiguousarray(self.sh_dc, dtype=np.float32).reshape(n, 3)
        if self.sh_rest is not None:
            rest = np.ascontiguousarray(self.sh_rest, dtype=np.float32)
            if rest.ndim != 3 or rest.shape[0] != n or rest.shape[2] != 3:
                raise ValueError(f"sh_rest must be (N, K-1, 3), got {rest.shape}")
            if rest.shape[1] == 0:
                rest = None
            elif rest.shape[1] + 1 not in (4, 9, 16):
                raise ValueError(f"sh_rest has {rest.shape[1]} coefficients: not an SH degree")
            self.sh_rest = rest
        if self.colour_space not in COLOUR_SPACES:
            raise ValueError(f"colour_space must be one of {COLOUR_SPACES}")

    @property
    def count(self) -> int:
        return int(self.means.shape[0])

    def __len__(self) -> int:
        return self.count

    @property
    def sh_degree(self) -> int:
        if self.sh_rest is None:
            return 0
        return {4: 1, 9: 2, 16: 3}[self.sh_rest.shape[1] + 1]

    def nothing_to_draw(self) -> str | None:
        """Why no Gaussian of the scene can show (there is none, or none reaches
        :data:`VISIBLE_OPACITY`), in words; None when one can."""
        if self.count == 0:
            return "no drawable Gaussian: the scene holds none"
        top = float(self.opacities.max())
        if not top >= VISIBLE_OPACITY:
            return (f"no drawable Gaussian: all {self.count:,} are transparent "
                    f"(the most opaque has opacity {top:.3g}, below 1/255)")
        return None

    def base_colour(self) -> np.ndarray:
        """(N, 3) float32: the view-independent colour max(SH_C0·dc + 0.5, 0)."""
        return np.maximum(SH_C0 * self.sh_dc + 0.5, 0.0).astype(np.float32)

    def robust_bounds(self, lo_pct: float = 2.0, hi_pct: float = 98.0) -> tuple[np.ndarray, np.ndarray]:
        """(3,), (3,) float64: per-axis percentile box of the means (outliers do not widen it)."""
        if self.count == 0:
            return np.full(3, -1.0), np.full(3, 1.0)
        lo = np.percentile(self.means, lo_pct, axis=0).astype(np.float64)
        hi = np.percentile(self.means, hi_pct, axis=0).astype(np.float64)
        return lo, hi

    def subset(self, keep: np.ndarray) -> "GaussianScene":
        """A new scene with only the Gaussians selected by ``keep`` (bool mask or indices)."""
        return GaussianScene(
            means=self.means[keep],
            quats=self.quats[keep],
            scales=self.scales[keep],
            opacities=self.opacities[keep],
            sh_dc=self.sh_dc[keep],
            sh_rest=None if self.sh_rest is None else self.sh_rest[keep],
            colour_space=self.colour_space,
            name=self.name,
        )

    def unit_quats(self) -> np.ndarray:
        """(N, 4) float64 unit quaternions (w, x, y, z); a zero or denormal one becomes identity."""
        q = self.quats.astype(np.float64)
        norm = np.linalg.norm(q, axis=1, keepdims=True)
        return np.where(norm > 1e-30, q / np.maximum(norm, 1e-300), np.array([1.0, 0, 0, 0]))

    def rotation_matrices(self) -> np.ndarray:
        """(N, 3, 3) float64 rotations R(q), world-from-local (so Σ = R S Sᵀ Rᵀ)."""
        return matrices_from_quats(self.unit_quats())


def matrices_from_quats(quats: np.ndarray) -> np.ndarray:
    """(N, 4) unit quaternions (w, x, y, z) → (N, 3, 3) float64 rotation matrices."""
    w, x, y, z = np.asarray(quats, np.float64).reshape(-1, 4).T
    return np.stack(
        [
            1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
        ],
        axis=1,
    ).reshape(-1, 3, 3)


def quat_from_matrix(m: np.ndarray) -> np.ndarray:
    """(3, 3) rotation matrix → (4,) float64 unit quaternion (w, x, y, z)."""
    m = np.asarray(m, np.float64)
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    # Shepperd's branch choice: divide by the largest of the four candidates for stability.
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    return q / np.linalg.norm(q)
