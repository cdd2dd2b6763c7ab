"""The part of a footprint inside a rectangle (footprint.clip_boxes), which the sliced mode's plan
boxes its layers with: never less than the ellipse's points in the rectangle (sampled densely),
the exact box where it can be worked out by hand (an ellipse holding the rectangle, a disk over a
corner), and a miss for needles that pass a corner without touching it, whose own boxes cover
the rectangle."""

import math

import numpy as np

from dofview.rendering.footprint import CLIP_INFLATE, clip_boxes

RECT = (-32.0, -32.0, 352.0, 272.0)


def _ellipses(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centres (n, 2), covariances (n, 3), r2 (n,)): sizes from half a pixel to 5000 px, any angle,
    centres far outside the rectangle too (splats at the lens)."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-4000.0, 4000.0, (n, 2))
    centres[: n // 2] = rng.uniform(-100.0, 450.0, (n // 2, 2))
    a, b = np.exp(rng.uniform(np.log(0.5), np.log(5000.0), (2, n)))
    t = rng.uniform(0.0, math.pi, n)
    c, s = np.cos(t), np.sin(t)
    cov = np.stack([a * a * c * c + b * b * s * s, (a * a - b * b) * c * s, a * a * s * s + b * b * c * c], 1) + [0.3, 0, 0.3]
    return centres, cov, rng.uniform(1.0, 11.0, n)


def _det(cov: np.ndarray) -> np.ndarray:
    return cov[:, 0] * cov[:, 2] - cov[:, 1] ** 2


def _inside_points(centre: np.ndarray, cov: np.ndarray, r2: float, samples: int = 400) -> np.ndarray:
    """(M, 2) points of the ellipse {d: dᵀΣ⁻¹d ≤ r2} (a polar grid of the unit disk mapped by
    Σ's square root) that lie in RECT."""
    l, v = np.linalg.eigh(np.array([[cov[0], cov[1]], [cov[1], cov[2]]]))
    root = v @ np.diag(np.sqrt(np.maximum(l, 0.0) * r2)) @ v.T
    rho, phi = np.meshgrid(np.sqrt(np.linspace(0.0, 1.0, samples)), np.linspace(0.0, 2 * math.pi, 4 * samples))
    pts = np.stack([rho.ravel() * np.cos(phi.ravel()), rho.ravel() * np.sin(phi.ravel())], 1) @ root.T + centre
    x0, y0, x1, y1 = RECT
    return pts[(pts[:, 0] >= x0) & (pts[:, 0] <= x1) & (pts[:, 1] >= y0) & (pts[:, 1] <= y1)]


def test_the_box_holds_every_point_of_the_ellipse_in_the_rectangle():
    centres, cov, r2 = _ellipses(300)
    boxes = clip_boxes(centres, cov, _det(cov), r2, RECT)
    missed = hit = 0
    for centre, c, q, box in zip(centres, cov, r2, boxes):
        pts = _inside_points(centre, c, q)
        if len(pts):
            hit += 1
            assert box[0] <= pts[:, 0].min() + 1e-6 and box[2] >= pts[:, 0].max() - 1e-6
            assert box[1] <= pts[:, 1].min() + 1e-6 and box[3] >= pts[:, 1].max() - 1e-6
        missed += box[0] > box[2] or box[1] > box[3]
    assert hit > 100 and missed > 50  # both kinds drawn


def test_exact_boxes_where_they_can_be_worked_out():
    x0, y0, x1, y1 = RECT
    # an ellipse holding the rectangle: the rectangle itself
    box = clip_boxes(np.array([[160.0, 120.0]]), np.array([[1e6, 2e5, 1e6]]), np.array([1e12 - 4e10]), np.array([9.0]),
                     RECT)[0]
    np.testing.assert_allclose(box, RECT)
    # a disk of radius 100 about the corner (x0, y0): the quarter inside, [x0, x0 + 100] × [y0, y0 + 100]
    r = 100.0 / math.sqrt(CLIP_INFLATE)  # the support is widened by CLIP_INFLATE
    box = clip_boxes(np.array([[x0, y0]]), np.array([[r * r, 0.0, r * r]]), np.array([r ** 4]), np.array([1.0]), RECT)[0]
    np.testing.assert_allclose(box, (x0, y0, x0 + 100.0, y0 + 100.0), rtol=0, atol=1e-9)


def test_a_needle_past_a_corner_misses_though_its_box_covers_the_rectangle():
    x1, y0 = RECT[2], RECT[1]
    for length in (1e3, 1e4):
        # along x − y = x1 − y0 + 20 (the rectangle has x − y ≤ x1 − y0), centred beside the
        # corner (x1, y0), 14 px from it, 1 px thick
        t = math.radians(45.0)
        c, s = math.cos(t), math.sin(t)
        a, b = length, 1.0
        cov = np.array([[a * a * c * c + b * b * s * s, (a * a - b * b) * c * s, a * a * s * s + b * b * c * c]])
        centre = np.array([[x1 + 10.0, y0 - 10.0]])
        ext = np.sqrt(9.0 * cov[0, [0, 2]])
        assert centre[0, 0] - ext[0] < RECT[0] and centre[0, 1] + ext[1] > RECT[3]  # its box covers the rectangle
        assert len(_inside_points(centre[0], cov[0], 9.0)) == 0
        box = clip_boxes(centre, cov, np.array([(a * b) ** 2]), np.array([9.0]), RECT)[0]
        assert box[0] > box[2] or box[1] > box[3]
