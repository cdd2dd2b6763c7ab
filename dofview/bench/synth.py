"""Deterministic procedural Gaussian scenes for the bundled samples, tests and benchmarks.

Everything here is numpy only and seeded: the same arguments always give bit-identical arrays.
The layouts are fixed, so the geometric facts below hold for every seed (the seed only varies
texture noise, glyphs and pebble placement).

All scenes are built for a canonical camera at the world origin looking along +z (OpenCV
convention, world y points *down*; "up" is −y), so a point's world z is its camera depth in the
canonical view. Scene units are arbitrary "metres".

* :func:`cards_scene` (sRGB, SH degree 0): three textured cards at canonical depths
  ``CARD_DEPTHS`` = near 2, mid 4, far 8; a brick wall at ``WALL_DEPTH`` = 14; a tiled ground
  plane at y = ``GROUND_Y`` with a few hundred pebbles on it.
* :func:`lamp_scene` (linear HDR radiance, SH degree 3): a room corner (floor + back wall at
  ``ROOM_BACK_DEPTH``) with three boxes, one of them glossy (non-zero ``sh_rest``), and a bright
  lamp bulb at ``LAMP_POSITION`` whose radiance is ≥ 100× that of any diffuse surface.
* :func:`random_scene`: n random Gaussians filling the view of :func:`benchmark_camera`.
* :func:`single_gaussian`: one isotropic Gaussian, for lens tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from dofview.bench.primitives import (
    IDENTITY_QUAT,
    Parts,
    add_panel,
    dc_from_colour,
    grid,
    orbit_cameras,
    yaw_matrix,
)
from dofview.camera import Camera, look_at
from dofview.lens import Lens, aperture_for_blur
from dofview.scene import (
    SH_C0,
    ColourSpace,
    GaussianScene,
    quat_from_matrix,
    sh_coeff_count,
)

CANONICAL_FOV_DEG = 60.0
"""Horizontal field of view (degrees) of the sample cameras."""

NOMINAL_SIZE = (800, 600)
"""(width, height) in pixels of the cameras written next to the bundled samples."""

# Disc Gaussians use a standard deviation of 0.6 × the texel spacing rather than 0.5: at 0.5 a
# grid of opacity-0.97 discs leaves ~16 % holes between texels (the wall would show through a
# card); at 0.6 the worst-covered point is still ~95 % covered, and a 4-texel-period pattern
# keeps ~64 % of its contrast.
_DISC_SIGMA = 0.6
# Thickness of a disc relative to its radius: thin enough to read as a surface seen edge-on.
_DISC_THICKNESS = 0.02
# Coplanar texels share one camera depth in the canonical view; a tiny seeded depth jitter
# (relative to depth) gives every sort a strict, reproducible order without visible relief.
_DEPTH_JITTER = 1e-4

# (yaw, pitch) in degrees; the first is the canonical front view, the rest a loose spiral that
# reaches ±20° of yaw and ~10° of pitch.
_ORBIT = [(0.0, 0.0), (-5.0, 0.0), (5.0, 0.0), (0.0, 5.0), (-10.0, 3.0), (10.0, 3.0),
          (-15.0, -2.0), (15.0, -2.0), (-20.0, 8.0), (20.0, 8.0)]


# --------------------------------------------------------------------------------------------
# Cards


@dataclass(frozen=True)
class Card:
    """A fronto-parallel square card of the cards scene.

    Attributes:
        name: "near", "mid" or "far".
        centre: (x, y, z) world position of the card centre, scene units; z is its canonical depth.
        size: side length, scene units.
        texels: texels (Gaussians) per side; the texel spacing is size / texels.
        pattern: "checker" (2-texel checks), "star" (Siemens star + stripes) or "text" (glyphs).
    """

    name: str
    centre: tuple[float, float, float]
    size: float
    texels: int
    pattern: str

    @property
    def depth(self) -> float:
        """Camera depth in the canonical view, scene units."""
        return float(self.centre[2])

    @property
    def spacing(self) -> float:
        """Texel spacing, scene units."""
        return self.size / self.texels

    def corners(self) -> np.ndarray:
        """(4, 3) float64 world corners (top-left, top-right, bottom-right, bottom-left)."""
        h = self.size / 2
        c = np.asarray(self.centre, np.float64)
        return c + np.array([[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]])

    def pixel_box(self, camera: Camera) -> tuple[float, float, float, float]:
        """(x0, y0, x1, y1) pixel bounding box of the card in ``camera`` (may exceed the image)."""
        px = camera.project(self.corners())
        return (float(px[:, 0].min()), float(px[:, 1].min()), float(px[:, 0].max()), float(px[:, 1].max()))


# Each card subtends the same angle (size / depth = 0.32, ~220 px of an 800-px-wide 60° view)
# and sits at its own place in the canonical image, so all three are fully visible (only the
# mid card's corner overlaps the far card, in front of it).
CARDS: tuple[Card, ...] = (
    Card("near", (-0.66, 0.24, 2.0), 0.64, 64, "checker"),
    Card("mid", (1.2, 0.32, 4.0), 1.28, 64, "star"),
    Card("far", (0.0, -1.6, 8.0), 2.56, 64, "text"),
)
CARD_DEPTHS: dict[str, float] = {c.name: c.depth for c in CARDS}
"""Canonical camera depth of each card (scene units): near 2, mid 4, far 8."""

WALL_DEPTH = 14.0
"""Canonical depth (world z) of the brick wall behind the cards."""

GROUND_Y = 1.5
"""World y of the ground plane (below the camera: world y points down)."""

_WALL_X = (-10.5, 10.5)
_WALL_TOP = -7.5
_WALL_SPACING = 0.22
_GROUND_X = (-10.0, 10.0)
_GROUND_Z = (2.5, WALL_DEPTH)
_GROUND_SPACING = 0.3
_PEBBLES = 400


def _card_colours(card: Card, rng: np.random.Generator) -> np.ndarray:
    """(texels, texels, 3) base colours of a card (row j from the top, column i from the left)."""
    n = card.texels
    i, j = grid(n, n)
    if card.pattern == "checker":
        on = ((i // 2 + j // 2) % 2).astype(bool)
        img = np.where(on[..., None], [0.92, 0.92, 0.9], [0.06, 0.06, 0.07])
        border = [0.85, 0.1, 0.1]
    elif card.pattern == "star":
        # Siemens star: contrast at every spatial frequency, so any defocus is visible.
        u, v = i - (n - 1) / 2, j - (n - 1) / 2
        spokes = 18
        theta = np.arctan2(v, u)
        inside = np.hypot(u, v) < 0.46 * n
        star = (np.floor((theta + np.pi) / (2 * np.pi) * 2 * spokes) % 2).astype(bool)
        stripes = ((i // 2) % 2).astype(bool)
        on = np.where(inside, star, stripes)
        img = np.where(on[..., None], [0.95, 0.92, 0.6], [0.05, 0.3, 0.1])
        border = [0.1, 0.7, 0.2]
    elif card.pattern == "text":
        # Rows of random 3×5 "glyphs" in 4×7 cells, with spaces between "words".
        img = np.broadcast_to(np.array([0.93, 0.9, 0.8]), (n, n, 3)).copy()
        margin, cw, ch = 3, 4, 7
        cols, rows = (n - 2 * margin) // cw, (n - 2 * margin) // ch
        glyphs = rng.random((rows, cols, 5, 3)) < 0.5
        blank = rng.random((rows, cols)) < 0.18
        for r in range(rows):
            for c in range(cols):
                if blank[r, c]:
                    continue
                y0, x0 = margin + 1 + r * ch, margin + c * cw
                img[y0:y0 + 5, x0:x0 + 3][glyphs[r, c]] = [0.08, 0.08, 0.15]
        border = [0.1, 0.2, 0.85]
    else:  # pragma: no cover - CARDS is fixed
        raise ValueError(card.pattern)
    edge = (i < 2) | (j < 2) | (i >= n - 2) | (j >= n - 2)
    img = np.where(edge[..., None], border, img)
    # A little per-texel noise, so the card is not unnaturally flat.
    img = img * (1.0 + rng.uniform(-0.03, 0.03, (n, n, 1)))
    return np.clip(img, 0.0, 1.0)


def _add_card(parts: Parts, card: Card, rng: np.random.Generator) -> None:
    n, s = card.texels, card.spacing
    i, j = grid(n, n)
    cx, cy, cz = card.centre
    x = cx + ((i + 0.5) / n - 0.5) * card.size
    y = cy + ((j + 0.5) / n - 0.5) * card.size
    z = cz * (1.0 + rng.uniform(-_DEPTH_JITTER, _DEPTH_JITTER, (n, n)))
    sigma = _DISC_SIGMA * s
    parts.add(np.stack([x, y, z], -1).reshape(-1, 3), [sigma, sigma, sigma * _DISC_THICKNESS],
              _card_colours(card, rng).reshape(-1, 3), 0.97)


def _add_wall(parts: Parts, rng: np.random.Generator) -> None:
    s = _WALL_SPACING
    nx = int(round((_WALL_X[1] - _WALL_X[0]) / s))
    ny = int(round((GROUND_Y - _WALL_TOP) / s))
    i, j = grid(nx, ny)
    x = _WALL_X[0] + (i + 0.5) * s
    y = _WALL_TOP + (j + 0.5) * s
    z = WALL_DEPTH * (1.0 + rng.uniform(-_DEPTH_JITTER, _DEPTH_JITTER, (ny, nx)))
    # Bricks 5×2 texels plus 1-texel mortar (≈ 1.1 × 0.44 units), alternate rows offset half a brick.
    row = j // 3
    col = (i + 3 * (row % 2)) // 6
    mortar = (j % 3 == 2) | ((i + 3 * (row % 2)) % 6 == 5)
    brick_tone = np.exp(rng.normal(0.0, 0.15, (row.max() + 1, col.max() + 1)))[row, col]
    brick = np.array([0.55, 0.22, 0.15]) * brick_tone[..., None]
    colours = np.where(mortar[..., None], [0.75, 0.73, 0.68], brick)
    colours = np.clip(colours * (1.0 + rng.uniform(-0.04, 0.04, (ny, nx, 1))), 0.0, 1.0)
    sigma = _DISC_SIGMA * s
    parts.add(np.stack([x, y, z], -1).reshape(-1, 3), [sigma, sigma, sigma * _DISC_THICKNESS],
              colours.reshape(-1, 3), 0.96)


def _add_ground(parts: Parts, rng: np.random.Generator) -> None:
    s = _GROUND_SPACING
    nx = int(round((_GROUND_X[1] - _GROUND_X[0]) / s))
    nz = int(round((_GROUND_Z[1] - _GROUND_Z[0]) / s))
    i, k = grid(nx, nz)
    x = _GROUND_X[0] + (i + 0.5) * s
    z = _GROUND_Z[0] + (k + 0.5) * s
    y = np.full_like(x, GROUND_Y) + rng.uniform(-1e-3, 1e-3, x.shape)
    tile = ((i // 4 + k // 4) % 2).astype(bool)
    colours = np.where(tile[..., None], [0.55, 0.5, 0.42], [0.4, 0.37, 0.32])
    colours = np.clip(colours * (1.0 + rng.uniform(-0.06, 0.06, (nz, nx, 1))), 0.0, 1.0)
    sigma = _DISC_SIGMA * s
    # Horizontal discs: thin along world y.
    parts.add(np.stack([x, y, z], -1).reshape(-1, 3), [sigma, sigma * _DISC_THICKNESS, sigma],
              colours.reshape(-1, 3), 0.95)


def _add_pebbles(parts: Parts, rng: np.random.Generator) -> None:
    n = _PEBBLES
    z = rng.uniform(2.8, 13.5, n)
    # Mostly inside the canonical view (|x/z| < tan 30° ≈ 0.58), a few just outside it.
    x = np.clip(rng.uniform(-0.65, 0.65, n) * z, -9.5, 9.5)
    size = np.exp(rng.normal(math.log(0.04), 0.35, n))
    scales = size[:, None] * np.stack([rng.uniform(0.8, 1.4, n), rng.uniform(0.4, 0.7, n),
                                       rng.uniform(0.8, 1.4, n)], 1)
    y = GROUND_Y - 1.5 * scales[:, 1]  # resting on the ground, not sunk into it
    phi = rng.uniform(0.0, 2 * np.pi, n)  # lying flat: random turn about the vertical only
    quats = np.stack([np.cos(phi / 2), np.zeros(n), np.sin(phi / 2), np.zeros(n)], 1)
    grey = rng.uniform(0.3, 0.8, n)[:, None]
    tint = np.array([1.0, 0.95, 0.85]) * rng.uniform(0.9, 1.1, (n, 3))
    parts.add(np.stack([x, y, z], 1), scales, np.clip(grey * tint, 0, 1), rng.uniform(0.9, 0.99, n), quats)


def cards_scene(seed: int = 0) -> GaussianScene:
    """Three textured cards at known depths, a brick wall, a ground plane and pebbles (sRGB).

    Layout (canonical camera at the origin looking along +z; see :data:`CARDS`):

    * near card, depth 2, left of centre, fine red-bordered black/white checkerboard;
    * mid card, depth 4, right of centre, green-bordered Siemens star + stripes;
    * far card, depth 8, above centre, blue-bordered rows of text-like glyphs;
      each card is 64×64 thin disc Gaussians (texel ≈ 3.5 px in the 800×600 nominal view);
    * brick wall at depth :data:`WALL_DEPTH` (14), ~21 × 9 units, coarse bricks;
    * tiled ground plane at y = :data:`GROUND_Y` (1.5) from depth 2.5 to 14, and 400 pebbles on it.

    SH degree 0, colour_space "srgb", opacities 0.9…0.99, 19 129 Gaussians (~1.5 MB as PLY).
    ``seed`` varies only noise, glyphs and pebbles; every position listed above is fixed.

    Returns:
        The scene, float32 arrays, name "cards".
    """
    rng = np.random.default_rng(seed)
    parts = Parts.empty()
    for card in CARDS:
        _add_card(parts, card, rng)
    _add_wall(parts, rng)
    _add_ground(parts, rng)
    _add_pebbles(parts, rng)
    return parts.build("srgb", "cards")


def cards_cameras(width: int = NOMINAL_SIZE[0], height: int = NOMINAL_SIZE[1]) -> list[Camera]:
    """10 views of the cards scene, names "view_000"…"view_009", horizontal FOV 60°.

    ``view_000`` is the canonical camera (origin, looking along +z, R = I, T = 0), in which card
    ``c`` is at depth ``c.depth``; the others orbit the point (0, 0, 5) by up to ±20° of yaw and
    −2…8° of pitch (raised and looking down).
    """
    return orbit_cameras((0.0, 0.0, 5.0), _ORBIT, width, height, CANONICAL_FOV_DEG)


# --------------------------------------------------------------------------------------------
# Lamp


LAMP_POSITION = (1.0, -0.55, 4.5)
"""World centre of the lamp bulb; its canonical camera depth is 4.5."""

LAMP_DEPTH = LAMP_POSITION[2]

LAMP_RADIUS = 0.15
"""Approximate visible radius of the bulb (cluster radius + 2σ of its Gaussians), scene units."""

LAMP_RADIANCE = (100.0, 85.0, 60.0)
"""Minimum linear radiance (base colour) of every bulb Gaussian, per channel."""

MAX_DIFFUSE_RADIANCE = 0.45
"""Upper bound of the base colour of every non-emissive Gaussian in :func:`lamp_scene`, all
channels; with the glossy box's view-dependent terms added (bounded by Σ|sh_rest| since every
real SH basis function of degree 1…3 is below 1 in magnitude) colours stay ≤ 0.6.
min(LAMP_RADIANCE) / MAX_DIFFUSE_RADIANCE ≈ 133."""

EMISSIVE_THRESHOLD = 1.0
"""In :func:`lamp_scene`, a Gaussian is part of the lamp bulb iff its base colour exceeds this
in some channel (use :func:`emissive_mask`)."""

FLOOR_Y = 1.2
"""World y of the lamp scene's floor (below the camera)."""

ROOM_BACK_DEPTH = 6.0
"""Canonical depth (world z) of the lamp scene's back wall."""

_ROOM_X = (-4.5, 4.5)
_ROOM_TOP = -3.2
_ROOM_FRONT = 1.5
_ROOM_SPACING = 0.14
_BOX_SPACING = 0.07
_GLOSSY_MAX_BASE = 0.3


@dataclass(frozen=True)
class _Box:
    x: float
    z: float
    size: tuple[float, float, float]  # width (x), height (up), depth (z), scene units
    yaw: float  # degrees about the vertical
    albedo: tuple[float, float, float]
    glossy: bool = False


_BOXES = (
    _Box(-1.3, 3.6, (0.8, 0.8, 0.8), 30.0, (0.2, 0.35, 0.8), glossy=True),
    _Box(1.0, 4.5, (0.7, 0.9, 0.7), -10.0, (0.8, 0.75, 0.65)),  # the lamp stands on this one
    _Box(-0.1, 5.2, (0.5, 0.5, 0.5), 10.0, (0.8, 0.3, 0.2)),
)


def _lit(points: np.ndarray, normals: np.ndarray, albedo: np.ndarray, cap: float) -> np.ndarray:
    """Fake direct + ambient lighting from the lamp (no shadows), then scaled to ≤ ``cap``.

    Returns (N, 3) float64 linear radiance. The scaling keeps hue: a texel whose brightest channel
    would exceed ``cap`` is dimmed as a whole, which is what keeps the 100× ratio guaranteed.
    """
    to_lamp = np.asarray(LAMP_POSITION) - points
    r2 = np.sum(to_lamp * to_lamp, axis=1)
    cos = np.maximum(np.sum(to_lamp * normals, axis=1) / np.sqrt(r2), 0.0)
    irradiance = 0.12 + 0.5 * cos / np.maximum(r2, 0.05)
    rad = albedo * irradiance[:, None]
    peak = rad.max(axis=1, keepdims=True)
    return np.where(peak > cap, rad * (cap / np.maximum(peak, 1e-12)), np.maximum(rad, 0.0))


def _add_room(parts: Parts, rng: np.random.Generator) -> None:
    s = _ROOM_SPACING
    sigma = _DISC_SIGMA * s
    nx = int(round((_ROOM_X[1] - _ROOM_X[0]) / s))
    # Floor: planks running along z, 3 texels (0.42 units) wide, each with its own tone.
    nz = int(round((ROOM_BACK_DEPTH - _ROOM_FRONT) / s))
    i, k = grid(nx, nz)
    x = _ROOM_X[0] + (i + 0.5) * s
    z = _ROOM_FRONT + (k + 0.5) * s
    y = FLOOR_Y + rng.uniform(-1e-3, 1e-3, x.shape)
    plank = np.exp(rng.normal(0.0, 0.12, i.max() // 3 + 1))[i // 3]
    albedo = np.array([0.55, 0.38, 0.22]) * plank[..., None] * (1 + rng.uniform(-0.05, 0.05, (nz, nx, 1)))
    pts = np.stack([x, y, z], -1).reshape(-1, 3)
    normal = np.broadcast_to([0.0, -1.0, 0.0], pts.shape)
    parts.add(pts, [sigma, sigma * _DISC_THICKNESS, sigma],
              _lit(pts, normal, albedo.reshape(-1, 3), MAX_DIFFUSE_RADIANCE), 0.97)
    # Back wall: pale plaster with a darker skirting board along the floor.
    ny = int(round((FLOOR_Y - _ROOM_TOP) / s))
    i, j = grid(nx, ny)
    x = _ROOM_X[0] + (i + 0.5) * s
    y = _ROOM_TOP + (j + 0.5) * s
    z = ROOM_BACK_DEPTH * (1.0 + rng.uniform(-_DEPTH_JITTER, _DEPTH_JITTER, x.shape))
    albedo = np.where((j >= ny - 2)[..., None], [0.25, 0.22, 0.2], [0.85, 0.83, 0.78])
    albedo = albedo * (1 + rng.uniform(-0.03, 0.03, (ny, nx, 1)))
    pts = np.stack([x, y, z], -1).reshape(-1, 3)
    normal = np.broadcast_to([0.0, 0.0, -1.0], pts.shape)
    parts.add(pts, [sigma, sigma, sigma * _DISC_THICKNESS],
              _lit(pts, normal, albedo.reshape(-1, 3), MAX_DIFFUSE_RADIANCE), 0.97)


def _add_box(parts: Parts, box: _Box, rng: np.random.Generator, degree: int) -> None:
    w, h, d = box.size
    rot = yaw_matrix(box.yaw)
    centre = np.array([box.x, FLOOR_Y - h / 2, box.z])
    # Faces as (normal, u axis, v axis, half extents along u, v) in box coordinates;
    # the bottom face rests on the floor and is never seen.
    faces = [
        ((0, -1, 0), (1, 0, 0), (0, 0, 1), w / 2, d / 2, h / 2),  # top
        ((0, 0, -1), (1, 0, 0), (0, 1, 0), w / 2, h / 2, d / 2),  # front
        ((0, 0, 1), (-1, 0, 0), (0, 1, 0), w / 2, h / 2, d / 2),  # back
        ((-1, 0, 0), (0, 0, -1), (0, 1, 0), d / 2, h / 2, w / 2),  # left
        ((1, 0, 0), (0, 0, 1), (0, 1, 0), d / 2, h / 2, w / 2),  # right
    ]
    cap = _GLOSSY_MAX_BASE if box.glossy else MAX_DIFFUSE_RADIANCE
    for normal, u_ax, v_ax, hu, hv, offset in faces:
        n_ax, u_ax, v_ax = (np.asarray(a, np.float64) for a in (normal, u_ax, v_ax))
        nu = max(2, int(round(2 * hu / _BOX_SPACING)))
        nv = max(2, int(round(2 * hv / _BOX_SPACING)))
        i, j = grid(nu, nv)
        u = (-hu + (i + 0.5) * (2 * hu / nu)).reshape(-1, 1)
        v = (-hv + (j + 0.5) * (2 * hv / nv)).reshape(-1, 1)
        local = n_ax * offset + u * u_ax + v * v_ax
        pts = centre + local @ rot.T
        normal_w = np.broadcast_to(rot @ n_ax, pts.shape)
        albedo = np.asarray(box.albedo) * (1 + rng.uniform(-0.04, 0.04, (len(pts), 1)))
        colour = _lit(pts, normal_w, albedo, cap)
        # Disc frame: local x, y along the face, local z along its normal.
        quat = quat_from_matrix(rot @ np.stack([u_ax, v_ax, n_ax], 1))
        su, sv = _DISC_SIGMA * 2 * hu / nu, _DISC_SIGMA * 2 * hv / nv
        rest = None
        if box.glossy and degree > 0:
            rest = _glossy_rest(len(pts), rot @ n_ax, degree, rng)
        parts.add(pts, [su, sv, min(su, sv) * _DISC_THICKNESS], colour, 0.98, quat, rest)


def _glossy_rest(n: int, normal: np.ndarray, degree: int, rng: np.random.Generator) -> np.ndarray:
    """(n, K−1, 3) small view-dependent SH coefficients for a glossy-looking face.

    A degree-1 lobe that brightens the face (slightly bluish) when seen head-on and darkens it at
    grazing angles, plus faint random degree-2/3 detail. Σ|coefficients| per channel stays
    below 0.4, which bounds the view-dependent term (every SH basis value is < 1 in magnitude);
    the degree-1 lobe itself adds at most C1·0.2 ≈ 0.1.
    """
    k = sh_coeff_count(degree) - 1
    rest = np.zeros((n, k, 3))
    # The 3DGS degree-1 term is C1·(−y·c0 + z·c1 − x·c2) for view direction (x, y, z): with
    # c = a·(−l_y, l_z, −l_x) it is C1·a·(dir · l), largest when looking along l.
    view_dir = -np.asarray(normal, np.float64)  # looking straight at the face
    lobe = 0.2 * np.array([-view_dir[1], view_dir[2], -view_dir[0]])
    rest[:, 0:3, :] = lobe[None, :, None] * np.array([0.8, 0.9, 1.0])  # a cool highlight
    if k > 3:
        rest[:, 3:, :] = rng.uniform(-0.01, 0.01, (n, k - 3, 3))
    return rest


def _add_lamp(parts: Parts, rng: np.random.Generator) -> None:
    centre = np.asarray(LAMP_POSITION, np.float64)
    # Pole from the stand box's top up to the bulb: dark metal, lit like the other surfaces.
    stand = _BOXES[1]
    top = FLOOR_Y - stand.size[1]
    y = np.arange(top - 0.015, centre[1] + 0.09, -0.03)
    pts = np.stack([np.full_like(y, centre[0]), y, np.full_like(y, centre[2])], 1)
    normal = np.broadcast_to([0.0, 0.0, -1.0], pts.shape)
    parts.add(pts, [0.015, 0.02, 0.015], _lit(pts, normal, np.array([[0.15, 0.15, 0.16]]), MAX_DIFFUSE_RADIANCE), 0.98)
    # Bulb: a Fibonacci-sphere shell plus a small core, so it reads as a solid glowing ball.
    shell = 120
    t = (np.arange(shell) + 0.5) / shell
    polar, azim = np.arccos(1 - 2 * t), np.pi * (1 + 5 ** 0.5) * np.arange(shell)
    dirs = np.stack([np.sin(polar) * np.cos(azim), np.sin(polar) * np.sin(azim), np.cos(polar)], 1)
    core = rng.normal(0.0, 1.0, (30, 3))
    core = 0.04 * core / np.linalg.norm(core, axis=1, keepdims=True) * rng.uniform(0, 1, (30, 1)) ** (1 / 3)
    pts = np.concatenate([centre + 0.09 * dirs, centre + core])
    scales = np.concatenate([np.full((shell, 3), 0.03), np.full((30, 3), 0.04)])
    radiance = np.asarray(LAMP_RADIANCE) * rng.uniform(1.0, 1.1, (len(pts), 1))  # never below LAMP_RADIANCE
    parts.add(pts, scales, radiance, 0.99)


def lamp_scene(seed: int = 0) -> GaussianScene:
    """A dim room corner with a very bright lamp bulb, in linear HDR radiance, SH degree 3.

    Layout (canonical camera at the origin looking along +z):

    * floor (wooden planks) at y = :data:`FLOOR_Y` (1.2) from depth 1.5 to 6, and a plaster back
      wall at depth :data:`ROOM_BACK_DEPTH` (6), both 9 units wide;
    * three boxes on the floor: a glossy blue one (left, depth ≈ 3.6, the only Gaussians with
      non-zero ``sh_rest``), a beige stand (right, depth ≈ 4.5) and a small red one (depth ≈ 5.2);
    * a lamp: a thin pole on the stand and a bulb of 150 Gaussians centred at
      :data:`LAMP_POSITION` (depth 4.5), radius ≈ :data:`LAMP_RADIUS`, base radiance ≥
      :data:`LAMP_RADIANCE` = (100, 85, 60) per channel.

    Diffuse radiance is albedo × fake lamp lighting, 0.03…:data:`MAX_DIFFUSE_RADIANCE` (0.45) in
    every channel, so the dimmest bulb channel is ≥ 133× the brightest diffuse channel.
    colour_space "linear", 5 677 Gaussians (~1.4 MB as PLY).

    Returns:
        The scene, float32 arrays, sh_rest (N, 15, 3), name "lamp".
    """
    rng = np.random.default_rng(seed)
    parts = Parts.empty()
    _add_room(parts, rng)
    for box in _BOXES:
        _add_box(parts, box, rng, 3)
    _add_lamp(parts, rng)
    return parts.build("linear", "lamp", degree=3)


def emissive_mask(scene: GaussianScene, threshold: float = EMISSIVE_THRESHOLD) -> np.ndarray:
    """(N,) bool: Gaussians whose base colour exceeds ``threshold`` in some channel (the lamp)."""
    return np.any(scene.base_colour() > threshold, axis=1)


def lamp_cameras(width: int = NOMINAL_SIZE[0], height: int = NOMINAL_SIZE[1]) -> list[Camera]:
    """10 views of the lamp scene, names "view_000"…"view_009", horizontal FOV 60°.

    ``view_000`` is the canonical camera (origin, looking along +z); the others orbit the point
    (0, 0, 4.5) by up to ±20° of yaw and −2…8° of pitch.
    """
    return orbit_cameras((0.0, 0.0, LAMP_DEPTH), _ORBIT, width, height, CANONICAL_FOV_DEG)


# --------------------------------------------------------------------------------------------
# Benchmarks and lens tests


BENCHMARK_SIZE = (1280, 720)


def benchmark_camera(width: int = BENCHMARK_SIZE[0], height: int = BENCHMARK_SIZE[1]) -> Camera:
    """The camera :func:`random_scene` is built for: origin, looking along +z, 60° horizontal FOV."""
    return replace(look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), width, height, CANONICAL_FOV_DEG), name="benchmark")


def random_scene(n: int, degree: int = 0, seed: int = 0, extent: float = 10.0, *,
                 coverage: float | None = None) -> GaussianScene:
    """``n`` random Gaussians filling the view of :func:`benchmark_camera` (1280×720, 60°).

    Means fill the camera's frustum (10 % beyond its edges) between depths 0.2·extent and
    2·extent (2…20 scene units by default), uniform in depth. Rotations are uniformly random;
    scales are log-normal, with per-axis anisotropy, sized from the footprint they should have
    on screen: the median standard deviation is √(coverage·W·H / (4π·n)) pixels, so the n discs
    of radius 2σ cover the 1280×720 frame about ``coverage`` times. ``coverage`` defaults to
    4·(n/10⁴)^⅓ (4 at 10k, ~19 at 1M, ~32 at 5M), growing like real scenes' overlap does, which
    gives median footprints of ~5 px at 10k and ~1 px at 1M. Opacities are uniform in
    [0.05, 0.99]; base colours in [0.05, 0.95]; sh_rest (degree > 0) ~ N(0, 0.05²); sRGB.

    Vectorised, float32 throughout: 1M Gaussians take a fraction of a second and ~60 MB
    (degree 0; degree 3 adds 180 MB of sh_rest).

    Args:
        n: number of Gaussians (≥ 0).
        degree: SH degree 0…3.
        seed: random seed; equal arguments give identical arrays.
        extent: depth scale, scene units (see above).
        coverage: mean number of 2σ discs over a pixel; see above for the default.
    """
    if n < 0:
        raise ValueError(f"n must be ≥ 0, got {n}")
    if degree not in (0, 1, 2, 3):
        raise ValueError(f"degree must be 0…3, got {degree}")
    rng = np.random.default_rng(seed)
    f32 = np.float32
    width, height = BENCHMARK_SIZE
    cam = benchmark_camera()
    tan_x, tan_y = width / (2 * cam.fx), height / (2 * cam.fy)
    near, far = 0.2 * extent, 2.0 * extent

    z = rng.random(n, dtype=f32) * f32(far - near) + f32(near)
    means = np.empty((n, 3), f32)
    means[:, 0] = (rng.random(n, dtype=f32) * f32(2.2) - f32(1.1)) * f32(tan_x) * z
    means[:, 1] = (rng.random(n, dtype=f32) * f32(2.2) - f32(1.1)) * f32(tan_y) * z
    means[:, 2] = z

    quats = rng.standard_normal((n, 4), dtype=f32)
    quats /= np.maximum(np.linalg.norm(quats, axis=1, keepdims=True), f32(1e-12))

    if coverage is None:
        coverage = 4.0 * (max(n, 1) / 1e4) ** (1 / 3)
    sigma_px = math.sqrt(coverage * width * height / (4 * math.pi * max(n, 1)))
    # World σ that projects to sigma_px at depth z, times a log-normal size and anisotropy.
    size = z * f32(sigma_px / cam.fx) * np.exp(rng.standard_normal(n, dtype=f32) * f32(0.5))
    scales = np.exp(rng.standard_normal((n, 3), dtype=f32) * f32(0.35))
    scales *= size[:, None]

    opacities = rng.random(n, dtype=f32) * f32(0.94) + f32(0.05)
    colour = rng.random((n, 3), dtype=f32) * f32(0.9) + f32(0.05)
    sh_dc = (colour - f32(0.5)) * f32(1.0 / SH_C0)
    sh_rest = None
    if degree > 0:
        sh_rest = rng.standard_normal((n, sh_coeff_count(degree) - 1, 3), dtype=f32)
        sh_rest *= f32(0.05)
    return GaussianScene(means=means, quats=quats, scales=scales, opacities=opacities, sh_dc=sh_dc,
                         sh_rest=sh_rest, colour_space="srgb", name="random")


ROOM_SIZE = (8.0, 3.0, 5.0)  # x, y, z extent of :func:`room_scene`, scene units


def room_scene() -> GaussianScene:
    """A room seen from nowhere (no cameras): 8 (x) × 3 (y) × 5 (z) units around the origin, world
    y down (−y up, the 3DGS convention): floor at y = 1.5, ceiling at −1.5, four walls of their own
    colours (x = −4 red, x = +4 green, z = −2.5 blue, z = +2.5 yellow), a table (top at y = 0.7)
    and a low sofa. ~19,000 thin Gaussians, SH degree 0, sRGB; no randomness."""
    parts = Parts.empty()
    hx, hy, hz = (e / 2 for e in ROOM_SIZE)
    x, y, z = (-hx, hx), (-hy, hy), (-hz, hz)
    add_panel(parts, 1, hy, {0: x, 2: z}, (0.55, 0.45, 0.35))  # floor
    add_panel(parts, 1, -hy, {0: x, 2: z}, (0.9, 0.9, 0.88))  # ceiling
    add_panel(parts, 0, -hx, {1: y, 2: z}, (0.8, 0.3, 0.3))
    add_panel(parts, 0, hx, {1: y, 2: z}, (0.3, 0.7, 0.3))
    add_panel(parts, 2, -hz, {0: x, 1: y}, (0.3, 0.3, 0.8))
    add_panel(parts, 2, hz, {0: x, 1: y}, (0.8, 0.8, 0.3))
    add_panel(parts, 1, 0.7, {0: (1.0, 2.5), 2: (-1.8, -0.6)}, (0.4, 0.25, 0.1), 0.05)  # table top
    add_panel(parts, 1, 1.0, {0: (-3.5, -1.5), 2: (1.2, 2.2)}, (0.2, 0.4, 0.6), 0.05)  # sofa seat
    add_panel(parts, 2, 2.2, {0: (-3.5, -1.5), 1: (0.2, 1.0)}, (0.2, 0.4, 0.6), 0.05)  # sofa back
    return parts.build("srgb", "room")


def _wall(parts: Parts, axis: int, at: float, span: dict[int, tuple[float, float]], colour,
          doors: tuple[tuple[float, float], ...] = ()) -> None:
    """A wall of :func:`furnished_room` (``add_panel``) with door openings ``doors`` ((lo, hi) along
    its horizontal span) from the floor (y = 0) up to y = −2.0, and lintels over them."""
    horizontal = next(a for a in span if a != 1)
    edges = [span[horizontal][0], *[e for d in sorted(doors) for e in d], span[horizontal][1]]
    for lo, hi in zip(edges[::2], edges[1::2]):
        add_panel(parts, axis, at, {horizontal: (lo, hi), 1: span[1]}, colour)
    for lo, hi in doors:
        add_panel(parts, axis, at, {horizontal: (lo, hi), 1: (span[1][0], -2.0)}, colour)


def furnished_room(length: float, width: float, height: float, *, doors: dict | None = None,
                   table: bool = False, floaters: int = 0, seed: int = 0, ceiling: bool = True) -> GaussianScene:
    """A place to open from inside: a room of thin Gaussians (``add_panel``, 0.1 apart), world y
    down, floor at y = 0, ceiling at y = −``height``, walls at x = ±length/2 and z = ±width/2 with
    door openings ``doors`` {"-x" | "+x" | "-z" | "+z": [(lo, hi), …]} 2.0 high. ``table``: a table
    in its middle (top 1.6 × 0.9 at 0.75 above the floor, four legs) and four chairs around it (seats
    0.44 square at 0.45, backs up to 0.9; all within x ±1.45, z ±1.05). ``floaters``: that many
    small splats (σ 0.01–0.04) scattered through the room, every third opaque (0.9), the others
    faint, as a capture leaves them. ``ceiling``: False leaves it out (a courtyard, or a room whose
    capture never looked up). SH degree 0, sRGB; seeded."""
    parts = Parts.empty()
    hx, hz = length / 2, width / 2
    doors = doors or {}
    add_panel(parts, 1, 0.0, {0: (-hx, hx), 2: (-hz, hz)}, (0.55, 0.45, 0.35))  # floor
    if ceiling:
        add_panel(parts, 1, -height, {0: (-hx, hx), 2: (-hz, hz)}, (0.9, 0.9, 0.88))
    for name, axis, at, span, colour in (("-x", 0, -hx, {1: (-height, 0.0), 2: (-hz, hz)}, (0.8, 0.3, 0.3)),
                                         ("+x", 0, hx, {1: (-height, 0.0), 2: (-hz, hz)}, (0.3, 0.7, 0.3)),
                                         ("-z", 2, -hz, {0: (-hx, hx), 1: (-height, 0.0)}, (0.3, 0.3, 0.8)),
                                         ("+z", 2, hz, {0: (-hx, hx), 1: (-height, 0.0)}, (0.8, 0.8, 0.3))):
        _wall(parts, axis, at, span, colour, tuple(doors.get(name, ())))
    if table:
        add_panel(parts, 1, -0.75, {0: (-0.8, 0.8), 2: (-0.45, 0.45)}, (0.4, 0.25, 0.1), 0.05)
        legs = [(x, y, z) for x in (-0.75, 0.75) for z in (-0.4, 0.4) for y in np.arange(-0.7, 0.0, 0.05)]
        parts.add(legs, (0.03, 0.03, 0.03), (0.3, 0.2, 0.1), 0.95)
        for cx, cz, facing in ((-1.2, 0.0, 0), (1.2, 0.0, 0), (0.0, -0.8, 2), (0.0, 0.8, 2)):
            seat = {0: (cx - 0.22, cx + 0.22), 2: (cz - 0.22, cz + 0.22)}
            add_panel(parts, 1, -0.45, seat, (0.2, 0.4, 0.6), 0.05)
            centre = cx if facing == 0 else cz
            back = {2 - facing: seat[2 - facing], 1: (-0.9, -0.45)}
            add_panel(parts, facing, centre + 0.25 * np.sign(centre), back, (0.2, 0.4, 0.6), 0.05)
    if floaters:
        rng = np.random.default_rng(seed)
        means = rng.uniform((-hx, -height, -hz), (hx, 0.0, hz), (floaters, 3))
        opacity = np.where(np.arange(floaters) % 3 == 0, 0.9, rng.uniform(0.05, 0.3, floaters))
        size = rng.uniform(0.01, 0.04, (floaters, 1)) * np.ones(3)
        parts.add(means, size, rng.uniform(0.0, 1.0, (floaters, 3)), opacity)
    return parts.build("srgb", "furnished room")


def _box(parts: Parts, lo, hi, colour, spacing: float, sides: str = "xyzXYZ") -> None:
    """The faces of the box ``lo``–``hi`` (3,) (world y down) named in ``sides`` ("x": its low-x face,
    "X": its high-x face, …) as panels of thin Gaussians ``spacing`` apart."""
    for name in sides:
        axis, end = "xyz".index(name.lower()), hi if name.isupper() else lo
        add_panel(parts, axis, end[axis], {a: (lo[a], hi[a]) for a in range(3) if a != axis}, colour, spacing)


def _tree(parts: Parts, x: float, z: float, height: float, crown: float, rng: np.random.Generator) -> None:
    """A tree on the ground (y = 0): a trunk 0.3 thick up to ``height`` − ``crown``, and a crown of
    leaves (splats σ 0.08–0.2, opaque) filling the sphere of radius ``crown`` under ``height``."""
    _box(parts, (x - 0.15, -(height - crown), z - 0.15), (x + 0.15, 0.0, z + 0.15), (0.35, 0.25, 0.15), 0.1, "xXzZ")
    n = int(600 * crown**2)
    d = rng.normal(size=(n, 3))
    d *= (crown * rng.uniform(0.6, 1.0, n) ** (1 / 3) / np.linalg.norm(d, axis=1))[:, None]
    centre = np.array([x, -(height - crown), z])
    green = np.array([0.2, 0.45, 0.15]) * rng.uniform(0.6, 1.2, (n, 1))
    parts.add(centre + d, rng.uniform(0.08, 0.2, (n, 1)) * np.ones(3), green, 0.95)


def garden_path(length: float = 14.0, width: float = 2.0, hedge: float = 1.8, seed: int = 0) -> GaussianScene:
    """A place in the open air, to open from inside: a gravel path ``width`` wide along x (x in
    ±length/2, |z| < width/2, ground at y = 0, world y down), lawns 2.5 wide beyond hedges 0.8 thick
    and ``hedge`` high along both its sides (each with one gap 1.2 wide), a tree 5 high behind each
    hedge every 4 along, a bench on one lawn; both ends of the path open, no ceiling, no sky.
    SH degree 0, sRGB; seeded."""
    rng = np.random.default_rng(seed)
    parts = Parts.empty()
    hx, hz = length / 2, width / 2
    add_panel(parts, 1, 0.0, {0: (-hx, hx), 2: (-hz, hz)}, (0.62, 0.58, 0.5), 0.08)  # gravel
    for side in (-1.0, 1.0):
        inner, outer = side * hz, side * (hz + 0.8)
        z0, z1 = sorted((outer, side * (hz + 3.3)))
        add_panel(parts, 1, 0.0, {0: (-hx, hx), 2: (z0, z1)}, (0.25, 0.5, 0.2), 0.12)  # lawn
        gap = 1.5 * side
        for x0, x1 in ((-hx, gap - 0.6), (gap + 0.6, hx)):  # the hedge, with a gap in it
            lo = (x0, -hedge, min(inner, outer))
            hi = (x1, 0.0, max(inner, outer))
            _box(parts, lo, hi, (0.15, 0.35, 0.12), 0.1, "xXzZy")
        for x in np.arange(-hx + 2.0, hx, 4.0):
            _tree(parts, x + side, side * (hz + 2.2), 5.0, 1.4, rng)
    _box(parts, (1.0, -0.45, hz + 1.2), (2.6, 0.0, hz + 1.7), (0.5, 0.35, 0.2), 0.05, "xXzZy")  # bench
    return parts.build("srgb", "garden path")


def street(length: float = 40.0, width: float = 12.0, facade: float = 10.0, seed: int = 0) -> GaussianScene:
    """A place in the open air: a street along x (x in ±length/2, ground at y = 0, world y down),
    façades ``facade`` high at z = ±width/2 with rows of dark windows set into them and a side
    street's opening on one side, pavements, two parked cars and lamp posts; both ends of the street
    open, no ceiling, no sky. SH degree 0, sRGB; seeded."""
    rng = np.random.default_rng(seed)
    parts = Parts.empty()
    hx, hz = length / 2, width / 2
    add_panel(parts, 1, 0.0, {0: (-hx, hx), 2: (-hz + 2.0, hz - 2.0)}, (0.3, 0.3, 0.32), 0.2)  # road
    for side in (-1.0, 1.0):
        z0, z1 = sorted((side * (hz - 2.0), side * hz))
        add_panel(parts, 1, -0.15, {0: (-hx, hx), 2: (z0, z1)}, (0.6, 0.58, 0.55), 0.2)  # pavement
        colour = (0.75, 0.6, 0.45) if side < 0 else (0.65, 0.65, 0.7)
        opening = (4.0, 10.0) if side > 0 else None  # a side street
        spans = [(-hx, opening[0]), (opening[1], hx)] if opening else [(-hx, hx)]
        for x0, x1 in spans:
            add_panel(parts, 2, side * hz, {0: (x0, x1), 1: (-facade, 0.0)}, colour, 0.2)
            for x in np.arange(x0 + 1.5, x1 - 1.0, 3.0):
                for y in np.arange(2.5, facade - 1.0, 3.0):
                    add_panel(parts, 2, side * (hz - 0.05), {0: (x, x + 1.2), 1: (-y - 1.5, -y)}, (0.08, 0.1, 0.14), 0.1)
        for x in np.arange(-hx + 4.0, hx, 8.0):  # lamp posts at the kerb
            _box(parts, (x - 0.06, -4.0, side * (hz - 2.3) - 0.06), (x + 0.06, -0.15, side * (hz - 2.3) + 0.06),
                 (0.2, 0.2, 0.2), 0.05, "xXzZ")
    for x, z in ((-6.0, -hz + 3.1), (7.0, hz - 3.1)):  # parked cars
        _box(parts, (x - 2.1, -1.4, z - 0.9), (x + 2.1, 0.0, z + 0.9), tuple(rng.uniform(0.2, 0.8, 3)), 0.1, "xXzZy")
    return parts.build("srgb", "street")


def receding_floor(width: int, height: int, blur: float) -> tuple[GaussianScene, Camera, Lens]:
    """The sliced mode's seam case: a uniform grey floor of thin Gaussians (x in ±4, y = 0.6 below
    the eye, z from 0.5 to 9; 27,200 splats, sRGB) seen from the origin towards (0, 0.35, 4) with a
    60° field of view at ``width`` × ``height`` px, focused at 3 with the aperture whose largest blur
    over depths 1–9 is ``blur`` px: it crosses a dozen depth layers and every reduced level."""
    parts = Parts.empty()
    add_panel(parts, 1, 0.6, {0: (-4.0, 4.0), 2: (0.5, 9.0)}, (0.6, 0.6, 0.6), spacing=0.05, opacity=0.98)
    camera = look_at((0.0, 0.0, 0.0), (0.0, 0.35, 4.0), width, height, 60.0)
    return parts.build("srgb", "floor"), camera, Lens(3.0, aperture_for_blur(blur, 3.0, 1.0, 9.0))


def single_gaussian(position, scale: float, opacity: float = 0.2, colour=(1.0, 1.0, 1.0), *,
                    colour_space: ColourSpace = "srgb") -> GaussianScene:
    """One isotropic Gaussian, for lens tests.

    Args:
        position: (3,) world position, scene units.
        scale: standard deviation, scene units (> 0).
        opacity: peak opacity in [0, 1].
        colour: (3,) base colour (SH degree 0), in ``colour_space``.
        colour_space: "srgb" (default, like :class:`GaussianScene`) or "linear".
    """
    if not scale > 0:
        raise ValueError(f"scale must be > 0, got {scale}")
    return GaussianScene(
        means=np.asarray(position, np.float32).reshape(1, 3),
        quats=IDENTITY_QUAT[None],
        scales=np.full((1, 3), scale, np.float32),
        opacities=np.array([opacity], np.float32),
        sh_dc=dc_from_colour(np.asarray(colour, np.float64).reshape(1, 3)),
        sh_rest=None,
        colour_space=colour_space,
        name="single",
    )
