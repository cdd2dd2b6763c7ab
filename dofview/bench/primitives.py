"""Building blocks of the synthetic scenes in :mod:`dofview.bench.synth`: a parts accumulator that
concatenates Gaussian groups into one scene, texel grids, rotations and orbit cameras."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from dofview.camera import Camera, look_at
from dofview.scene import SH_C0, ColourSpace, GaussianScene, sh_coeff_count

IDENTITY_QUAT = np.array([1.0, 0.0, 0.0, 0.0], np.float32)


def dc_from_colour(colour: np.ndarray) -> np.ndarray:
    """(…, 3) base colour → (…, 3) float32 SH DC coefficient (colour = SH_C0·dc + 0.5)."""
    return ((np.asarray(colour, np.float64) - 0.5) / SH_C0).astype(np.float32)


def yaw_matrix(yaw_deg: float) -> np.ndarray:
    """(3, 3) rotation about the world y axis (the vertical)."""
    a = math.radians(yaw_deg)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


@dataclass
class Parts:
    """Accumulates Gaussian groups, then concatenates them into one scene."""

    means: list
    quats: list
    scales: list
    opacities: list
    colours: list
    rest: list

    @classmethod
    def empty(cls) -> "Parts":
        return cls([], [], [], [], [], [])

    def add(self, means, scales, colours, opacities, quats=None, rest=None) -> None:
        n = len(means)
        self.means.append(np.asarray(means, np.float32).reshape(n, 3))
        self.scales.append(np.broadcast_to(np.asarray(scales, np.float32), (n, 3)))
        self.colours.append(np.broadcast_to(np.asarray(colours, np.float64), (n, 3)))
        self.opacities.append(np.broadcast_to(np.asarray(opacities, np.float32), (n,)))
        q = IDENTITY_QUAT if quats is None else quats
        self.quats.append(np.broadcast_to(np.asarray(q, np.float32), (n, 4)))
        self.rest.append(rest)

    def build(self, colour_space: ColourSpace, name: str, degree: int = 0) -> GaussianScene:
        sh_rest = None
        if degree > 0:
            k = sh_coeff_count(degree) - 1
            sh_rest = np.concatenate([
                np.zeros((len(m), k, 3), np.float32) if r is None else np.asarray(r, np.float32)
                for m, r in zip(self.means, self.rest)
            ])
        return GaussianScene(
            means=np.concatenate(self.means),
            quats=np.concatenate(self.quats),
            scales=np.concatenate(self.scales),
            opacities=np.concatenate(self.opacities),
            sh_dc=dc_from_colour(np.concatenate(self.colours)),
            sh_rest=sh_rest,
            colour_space=colour_space,
            name=name,
        )


_FACING = {0: (math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0),  # local z (the flat axis) onto x
           1: (math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0),  # … onto y
           2: (1.0, 0.0, 0.0, 0.0)}  # … z as it is


def add_panel(parts: "Parts", axis: int, at: float, span: dict[int, tuple[float, float]], colour,
              spacing: float = 0.1, opacity: float = 0.95) -> None:
    """A flat rectangle of thin Gaussians facing along world ``axis`` (0, 1, 2) at coordinate ``at``,
    covering ``span`` {each other axis: (lo, hi)}, one splat per ``spacing``² (scene units): walls,
    floors, table tops."""
    (b, (b0, b1)), (c, (c0, c1)) = sorted(span.items())
    u, v = np.meshgrid(np.arange(b0 + spacing / 2, b1, spacing), np.arange(c0 + spacing / 2, c1, spacing))
    means = np.zeros((u.size, 3))
    means[:, axis], means[:, b], means[:, c] = at, u.ravel(), v.ravel()
    parts.add(means, (0.6 * spacing, 0.6 * spacing, 0.03 * spacing), colour, opacity, _FACING[axis])


def grid(nu: int, nv: int) -> tuple[np.ndarray, np.ndarray]:
    """Texel indices (i along u, j along v), each (nv, nu) int."""
    j, i = np.mgrid[0:nv, 0:nu]
    return i, j


def orbit_cameras(pivot: tuple[float, float, float], angles: list[tuple[float, float]],
                   width: int, height: int, fov_deg: float) -> list[Camera]:
    """Cameras on a sphere around ``pivot`` through the origin, all looking at ``pivot``.

    ``angles`` are (yaw, pitch) in degrees: yaw swings the eye to the right (+x) around the
    vertical, pitch raises it (towards −y) so it looks down. (0, 0) is the canonical camera at
    the origin looking along +z with R = I, T = 0.
    """
    p = np.asarray(pivot, np.float64)
    radius = float(np.linalg.norm(p))
    cams = []
    for k, (yaw, pitch) in enumerate(angles):
        y, x = math.radians(yaw), math.radians(pitch)
        offset = radius * np.array([math.sin(y) * math.cos(x), -math.sin(x), -math.cos(y) * math.cos(x)])
        cam = look_at(p + offset, p, width, height, fov_deg)
        cams.append(replace(cam, name=f"view_{k:03d}"))
    return cams
