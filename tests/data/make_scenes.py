"""Make tests/data/two_planes.ply and tests/data/burger.ply, the stand-ins for two trained scenes
whose repositories carry no licence (tests/data/README.md), with dofview's own primitives.

    python tests/data/make_scenes.py      # writes both files next to this script

Seeded: the same code (and numpy) always writes the same bytes. Each keeps the traits the tests rely on:

* two_planes.ply: Inria-format PLY (normals, SH degree 3, no dofview comment), a ~0.7-unit object of
  two flat faces (a box's top, normal x, at the low-x end, and one side hanging from its edge), a
  halo of faint, large floaters and a few out to ~16 units in every direction: a framing trap.
* burger.ply: 14 properties (no normals, no f_rest: SH 0), a layered burger whose bun is on top
  in −y, stored with quaternions far from unit length (median norm ~0.006), as the image-to-3D
  generator of the original left them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.lib.recfunctions import repack_fields

from dofview.bench.primitives import Parts, grid
from dofview.io.ply import scene_rows
from dofview.scene import GaussianScene, quat_from_matrix

HERE = Path(__file__).resolve().parent
STORED_QUAT_NORM = 0.006  # median length of burger.ply's stored quaternions (the original's)
SIZE_SPREAD = 0.6  # burger: log-normal σ of splat sizes; the original's span 20× from 5th to 95th percentile
NEEDLES = 10.0  # burger: splats up to this many times longer than wide (the original's are needle-thin)


def _frames(normals: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(N, 4) unit quaternions whose local z axis is ``normals`` (N, 3), randomly turned about it."""
    n = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    helper = np.where(np.abs(n[:, 1:2]) > 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = np.cross(helper, n)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    phi = rng.uniform(0.0, 2 * np.pi, (len(n), 1))
    u, v = np.cos(phi) * t1 + np.sin(phi) * t2, -np.sin(phi) * t1 + np.cos(phi) * t2
    return np.array([quat_from_matrix(m) for m in np.stack([u, v, n], 2)])


def _surface(parts: Parts, points: np.ndarray, normals: np.ndarray, colours: np.ndarray, size: float,
             flatness: float, opacities, rng: np.random.Generator, rest=None, spread: float = 0.2,
             elongation: float = 1.0) -> None:
    """Splats on a surface: (N, 3) points and normals, (N, 3) colours in [0, 1]. Standard
    deviations: the long in-plane one around ``size`` (scene units; log-normal, σ = ``spread``), the
    short one up to ``elongation`` times smaller (log-uniform), ``flatness`` × that along the normal."""
    k = len(points)
    long = size * np.exp(rng.normal(0.0, spread, k))
    short = long * np.exp(rng.uniform(-np.log(elongation), 0.0, k))
    scales = np.column_stack([long, short, flatness * short])
    parts.add(points, scales, np.clip(colours, 0.0, 1.0), opacities, _frames(normals, rng), rest)


def _glyphs(nu: int, nv: int, cell: int, rng: np.random.Generator) -> np.ndarray:
    """(nv, nu) bool: rows of random 3×5 glyphs in (cell+1)×(cell+3) cells, a text-like pattern."""
    ink = np.zeros((nv, nu), bool)
    for y0 in range(2, nv - 6, cell + 3):
        for x0 in range(2, nu - 4, cell + 1):
            if rng.random() > 0.15:
                ink[y0:y0 + 5, x0:x0 + 3] = rng.random((5, 3)) < 0.5
    return ink


def two_planes_scene(seed: int = 0) -> GaussianScene:
    """The shape of the original capture: the top of a box (normal x, at the low-x end of the
    object, 0.7 × 0.7 units at x = 0.36) with one side hanging 0.35 units from its low-y edge
    (normal y, text-like glyphs), SH degree 3 with small view-dependent terms, and 500 faint,
    large floaters: 400 in a halo 0.42–0.6 units from the middle, 100 from 2 out to 16 units."""
    rng = np.random.default_rng(seed)
    parts = Parts.empty()
    k_rest = 15
    spacing = 0.0125

    nu = nv = 56  # the top: y and z
    i, j = grid(nu, nv)
    y, z = 1.93 + (i + 0.5) * spacing, 2.82 + (j + 0.5) * spacing
    pts = np.stack([np.full(y.shape, 0.36), y, z], -1).reshape(-1, 3)
    pts[:, 0] += rng.uniform(-1e-4, 1e-4, len(pts))
    check = ((i // 4 + j // 4) % 2).astype(bool).reshape(-1)
    col = np.where(check[:, None], [0.85, 0.82, 0.74], [0.55, 0.35, 0.3])
    _surface(parts, pts, np.tile([1.0, 0.0, 0.0], (len(pts), 1)), col, 0.6 * spacing, 0.05, 0.95, rng,
             rng.normal(0.0, 0.05, (len(pts), k_rest, 3)))

    nu, nv = 56, 28  # the side: z (across) and x (hanging from the top's edge)
    i, j = grid(nu, nv)
    z, x = 2.82 + (i + 0.5) * spacing, 0.36 + (j + 0.5) * spacing
    pts = np.stack([x, np.full(x.shape, 1.93), z], -1).reshape(-1, 3)
    ink = _glyphs(nu, nv, 3, rng).reshape(-1)
    col = np.where(ink[:, None], [0.08, 0.08, 0.12], [0.92, 0.92, 0.95])
    _surface(parts, pts, np.tile([0.0, 1.0, 0.0], (len(pts), 1)), col, 0.6 * spacing, 0.05, 0.95, rng,
             rng.normal(0.0, 0.05, (len(pts), k_rest, 3)))

    # floaters, as the original's: a faint halo just outside the object and a few far out, all larger
    # than the object's splats (so framing weighs them little)
    centre = np.array([0.53, 2.27, 3.17])
    for n, r0, r1, size in ((400, 0.42, 0.6, 0.03), (100, 2.0, 16.0, 0.05)):
        d = rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        r = np.exp(rng.uniform(np.log(r0), np.log(r1), n))
        parts.add(centre + d * r[:, None], np.exp(rng.normal(np.log(size), 0.4, (n, 3))),
                  rng.uniform(0.05, 0.5, (n, 3)), np.exp(rng.uniform(np.log(0.02), np.log(0.5), n)),
                  _frames(rng.normal(size=(n, 3)), rng), rng.normal(0.0, 0.05, (n, k_rest, 3)))
    return parts.build("srgb", "two_planes", degree=3)


def _disc(n: int, radius: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(n,), (n,): x and z of ``n`` points spread evenly over a disc (sunflower spiral), jittered."""
    k = np.arange(n) + 0.5
    r = radius * np.sqrt(k / n)
    a = k * np.pi * (3.0 - np.sqrt(5.0)) + rng.uniform(-0.2, 0.2, n)
    return r * np.cos(a), r * np.sin(a)


def _ring(n: int, radius: float, y0: float, y1: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) points on a cylinder's side (axis y, from y0 to y1) and their (n, 3) outward normals."""
    a = rng.uniform(0.0, 2 * np.pi, n)
    y = rng.uniform(y0, y1, n)
    normals = np.stack([np.cos(a), np.zeros(n), np.sin(a)], 1)
    return normals * radius + np.stack([np.zeros(n), y, np.zeros(n)], 1), normals


def _opacities(n: int, rng: np.random.Generator) -> np.ndarray:
    """(n,): surfaces made mostly of faint splats (75 %: 0.05…0.35), the rest nearly opaque. Much of
    the original's light under blur is in splats of opacity 0.1…0.3, which the anchors' α ≥ 1/255
    cut drops (clamping its opacities to ≥ 0.3 takes the conserving cut's gain over the anchors from
    +1.3 dB to +0.1 dB); test_dof_kernel.py relies on that gain."""
    return np.where(rng.random(n) < 0.75, rng.uniform(0.05, 0.35, n), rng.uniform(0.7, 1.0, n))


def burger_scene(seed: int = 0) -> GaussianScene:
    """A burger ~0.9 units across and 0.75 tall (world y down, so its bun is on top in −y): sesame
    dome, cheese, tomato, lettuce, patty and a bottom bun with a flat base (the ground that
    framing finds), and small, faint splats filling its inside."""
    rng = np.random.default_rng(seed)
    parts = Parts.empty()

    n = 9000  # top bun: a half-ellipsoid above y = -0.08; rounded splats, so it is no ground
    d = rng.normal(size=(n, 3))
    d[:, 1] = -np.abs(d[:, 1])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    radii = np.array([0.45, 0.29, 0.45])
    pts = np.array([0.0, -0.08, 0.0]) + d * radii
    seeds = rng.normal(size=(160, 3))
    seeds[:, 1] = -np.abs(seeds[:, 1]) - 0.3  # sesame on the upper part of the dome only
    seeds /= np.linalg.norm(seeds, axis=1, keepdims=True)
    sesame = np.min(np.linalg.norm(d[:, None] - seeds[None], axis=2), 1) < 0.035
    col = np.where(sesame[:, None], [0.95, 0.9, 0.72], [0.78, 0.48, 0.18]) * rng.uniform(0.9, 1.1, (n, 1))
    _surface(parts, pts, d / radii, col, 0.008, 0.5, _opacities(n, rng), rng, spread=SIZE_SPREAD, elongation=NEEDLES)

    n = 2500  # cheese: a square turned 45°, its corners drooping
    u, v = rng.uniform(-0.4, 0.4, (2, n))
    x, z = (u - v) / np.sqrt(2), (u + v) / np.sqrt(2)
    y = -0.05 + 0.6 * np.maximum(np.hypot(x, z) - 0.35, 0.0) ** 2
    _surface(parts, np.stack([x, y, z], 1), np.tile([0.0, 1.0, 0.0], (n, 1)),
             np.tile([0.98, 0.72, 0.08], (n, 1)), 0.01, 0.1, _opacities(n, rng), rng,
             spread=SIZE_SPREAD, elongation=NEEDLES)

    for n, radius, y, colour, flatness in ((2000, 0.42, -0.02, (0.85, 0.15, 0.1), 0.1),  # tomato
                                           (3000, 0.48, 0.01, (0.3, 0.65, 0.18), 0.5)):  # crinkled lettuce
        x, z = _disc(n, radius, rng)
        yy = y + 0.025 * np.sin(9 * np.arctan2(z, x)) * (np.hypot(x, z) > 0.3)
        _surface(parts, np.stack([x, yy, z], 1), np.tile([0.0, 1.0, 0.0], (n, 1)),
                 np.array(colour) * rng.uniform(0.85, 1.15, (n, 1)), 0.012, flatness, _opacities(n, rng), rng,
                 spread=SIZE_SPREAD, elongation=NEEDLES)

    for n, radius, y0, y1, colour in ((3000, 0.43, 0.04, 0.16, (0.33, 0.19, 0.11)),  # patty
                                      (2500, 0.44, 0.18, 0.34, (0.8, 0.55, 0.28))):  # bottom bun's side
        pts, normals = _ring(n, radius, y0, y1, rng)
        _surface(parts, pts, normals, np.array(colour) * rng.uniform(0.8, 1.2, (n, 1)), 0.009, 0.5,
                 _opacities(n, rng), rng, spread=SIZE_SPREAD, elongation=NEEDLES)

    n = 2500  # the bottom bun's flat base, at the bottom (high y)
    x, z = _disc(n, 0.43, rng)
    _surface(parts, np.stack([x, np.full(n, 0.37), z], 1), np.tile([0.0, 1.0, 0.0], (n, 1)),
             np.tile([0.7, 0.45, 0.22], (n, 1)), 0.01, 0.05, rng.uniform(0.7, 1.0, n), rng)

    n = 6000  # the inside: small, faint, round splats
    x, z = _disc(n, 0.4, rng)
    parts.add(np.stack([x, rng.uniform(-0.3, 0.33, n), z], 1), np.exp(rng.normal(np.log(0.006), 0.5, (n, 3))),
              rng.uniform(0.3, 0.8, (n, 3)), rng.uniform(0.005, 0.2, n), _frames(rng.normal(size=(n, 3)), rng))
    return parts.build("srgb", "burger")


def write_foreign_ply(scene: GaussianScene, path: Path, normals: bool, quat_norms: np.ndarray | None = None) -> None:
    """``scene`` as another tool would store it: no dofview comment, normals (zero, as the Inria
    trainer writes them) only if ``normals``; stored quaternions of length ``quat_norms`` (N,) if given."""
    rows = scene_rows(scene)
    names = [n for n in rows.dtype.names if normals or n not in ("nx", "ny", "nz")]
    rows = repack_fields(rows[names])
    if quat_norms is not None:
        for i in range(4):
            rows[f"rot_{i}"] *= quat_norms.astype(np.float32)
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {scene.count}"]
    header += [f"property float {n}" for n in names] + ["end_header"]
    path.write_bytes(("\n".join(header) + "\n").encode("ascii") + rows.tobytes())


def main() -> None:
    two_planes = two_planes_scene()
    write_foreign_ply(two_planes, HERE / "two_planes.ply", normals=True)
    burger = burger_scene()
    norms = np.exp(np.random.default_rng(1).normal(np.log(STORED_QUAT_NORM), 0.5, burger.count))
    write_foreign_ply(burger, HERE / "burger.ply", normals=False, quat_norms=norms)
    for s in (two_planes, burger):
        print(f"{s.name}.ply: {s.count} Gaussians, SH degree {s.sh_degree}")


if __name__ == "__main__":
    main()
