"""Where to put the first camera: a scene's robust extent, its up axis, and the centre and up of
a set of training views.

Without cameras a scene is framed from its opacity-weighted percentile box (floaters and
near-transparent haze do not shrink the object to a dot), looked at slightly from above along the
world up that :func:`guess_up` finds; a scene that surrounds its centre (a room) is seen from
inside. With cameras the orbit pivot is the point nearest to all their optical axes and world up
is their mean up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from dofview.camera import Camera, look_at
from dofview.errors import DofviewError
from dofview.scene import GaussianScene

UP_AXES: tuple[str, ...] = ("-y", "+z", "+y", "-z", "+x", "-x")
"""World up directions ``--up`` takes, in the order the viewer's key cycles them. −y first: the
3DGS/COLMAP convention (OpenCV camera axes, y down), which PLY, SuperSplat and SPZ-read-as-PLY share."""

CONVENTION_BONUS = 1.5  # −y's ground evidence counts this much more (the convention breaks near-ties)
DOMINANCE = 1.5  # a ground must be this many times stronger than the next side's
ELONGATION = 1.5  # without a ground, an axis this many times longer than the others is up (a standing figure)
FLAT_RATIO = 0.3  # a Gaussian is flat when its smallest scale is below this fraction of the middle one
GROUND_BAND = 0.25  # the ground is sought in this fraction of the box along each direction
MIN_GROUND_SHARE = 0.2  # below this share of the flat mass there is no ground to speak of
RIM = 0.1  # a face's middle is its footprint less this fraction of it on every side
CARRIED_SHARE = 0.01  # a face with less of the rest over its middle (and not under its centre) carries nothing
WALL_SHARE = 0.05  # a wall holds at least this share of the flat mass
WALL_THICKNESS = 0.05  # and its middle 80 % lies within this fraction of the box's extent
CORE = 0.25  # the middle of the box: this fraction of its half-extent around its centre
EMPTY_CORE = 0.01  # a middle holding less than this share of the scene's weight is empty
INSIDE_BACK = 0.5  # seen from inside, the camera stands this fraction of the half-length behind the centre
ELEVATION_DEG = 20.0  # the overview camera looks down on the scene by this much
SAMPLE = 200_000  # statistics are taken over at most this many Gaussians (an even stride through the file)
FILL = 0.8  # the box's corners fill this fraction of the frame (the 2–98 % box leaves tails out)


def axis_vector(label: str) -> np.ndarray:
    """(3,) float64 unit vector of an axis label such as ``"-y"``."""
    if label not in UP_AXES:
        raise DofviewError(f"up axis must be one of {', '.join(UP_AXES)}, got {label!r}")
    v = np.zeros(3)
    v["xyz".index(label[1])] = 1.0 if label[0] == "+" else -1.0
    return v


def weighted_quantiles(values: np.ndarray, weights: np.ndarray, q) -> np.ndarray:
    """Quantiles ``q`` (in [0, 1]) of ``values`` (N,) where each value counts ``weights`` (N,) ≥ 0."""
    order = np.argsort(values, kind="stable")
    cum = np.cumsum(np.asarray(weights, np.float64)[order])
    if cum[-1] <= 0:
        return np.quantile(values, q)
    mid = (cum - 0.5 * np.asarray(weights, np.float64)[order]) / cum[-1]
    return np.interp(q, mid, np.asarray(values, np.float64)[order])


def _sample(scene: GaussianScene) -> GaussianScene:
    """At most :data:`SAMPLE` Gaussians, every k-th: percentiles and shares need no more."""
    step = -(-scene.count // SAMPLE)
    # framing reads positions, sizes, opacities and rotations only: leave the SH rest uncopied
    return scene if step <= 1 else replace(scene, sh_rest=None).subset(np.arange(0, scene.count, step))


def framing_weights(scene: GaussianScene) -> np.ndarray:
    """(N,) float64: how much each Gaussian counts when framing: its opacity, divided by how many
    times larger than the median Gaussian it is. Faint floaters and the few huge splats of a
    backdrop (a sky sphere around a scan) then count for little; the detailed object for much."""
    size = scene.scales.max(axis=1).astype(np.float64)
    typical = max(float(np.median(size)), 1e-12)
    return scene.opacities.astype(np.float64) * np.minimum(1.0, typical / np.maximum(size, 1e-30))


def robust_box(scene: GaussianScene, lo_pct: float = 2.0, hi_pct: float = 98.0) -> tuple[np.ndarray, np.ndarray]:
    """(3,), (3,) float64: per-axis percentiles of the means, each Gaussian weighted by
    :func:`framing_weights`, so that floaters and backdrops neither widen the box nor pull it off
    the object."""
    if scene.count == 0:
        return np.full(3, -1.0), np.full(3, 1.0)
    scene = _sample(scene)
    w = framing_weights(scene)
    qs = [lo_pct / 100.0, hi_pct / 100.0]
    box = np.array([weighted_quantiles(scene.means[:, a], w, qs) for a in range(3)])
    return box[:, 0], box[:, 1]


def extent(scene: GaussianScene) -> tuple[np.ndarray, float]:
    """(centre (3,), radius): the middle and half-diagonal of :func:`robust_box`, scene units."""
    lo, hi = robust_box(scene)
    return (lo + hi) / 2, max(float(np.linalg.norm(hi - lo)) / 2, 1e-6)


@dataclass(frozen=True)
class UpGuess:
    """A world up: ``label`` (one of :data:`UP_AXES`, or ``"x,y,z"`` for any direction) and why, in words."""

    label: str
    reason: str = "given"

    @property
    def vector(self) -> np.ndarray:
        """(3,) float64 unit vector."""
        if self.label in UP_AXES:
            return axis_vector(self.label)
        v = np.array([float(c) for c in self.label.split(",")])
        return v / np.linalg.norm(v)

    @property
    def nearest_axis(self) -> str:
        """The label of :data:`UP_AXES` closest to :attr:`vector`."""
        return nearest_axis(self.vector)


def nearest_axis(up: np.ndarray) -> str:
    """The label of :data:`UP_AXES` closest to the direction ``up`` (3,)."""
    return max(UP_AXES, key=lambda a: float(axis_vector(a) @ up))


def guess_up(scene: GaussianScene) -> UpGuess:
    """Guess which world axis is up: from the scene's ground, else its tall axis, else the convention.

    1. Ground. Trained scenes rest on something: a floor, a table, a ground plane, the flat base of
       an object. Those surfaces are fitted by flat Gaussians whose normal (the axis of the smallest
       scale) is along up, and they lie at the bottom of the scene. For each of the six axis
       directions d the score is the flat mass (opacity × area of the flat face) whose normal lies
       along d, among the Gaussians in the lowest quarter of the box along d, as a share of all
       flat mass (−y's counts ×1.5). A ground holds ≥ 20 % of the flat mass and ≥ 1.5× the next
       side's score, and carries the scene (:func:`_carried`); one that carries nothing is an
       object's top, the sides of a box hanging from its edges, and up points towards it.
    2. Tall axis. Without a ground (a figure, a statue, a guitar), a box ≥ 1.5× longer along one
       axis than along the others stands on it; the sign is the convention's (−y, +z, +x).
    3. Otherwise −y, the 3DGS/COLMAP convention.
    """
    if scene.count == 0:
        return UpGuess("-y", "empty scene: the 3DGS convention")
    scene = _sample(scene)
    ground = _ground(scene)
    if ground is not None:
        return ground
    lo, hi = robust_box(scene)
    size = hi - lo
    a = int(np.argmax(size))
    others = float(np.max(np.delete(size, a)))
    if size[a] >= ELONGATION * others:
        label = ("-y", "+z", "+x")[(1, 2, 0).index(a)]
        return UpGuess(label, f"no ground; the scene stands {size[a] / max(others, 1e-12):.1f}× taller along "
                              f"{'xyz'[a]} than across (sign by convention)")
    return UpGuess("-y", "no ground and no tall axis: the 3DGS convention")


def _flat_mass(scene: GaussianScene) -> tuple[np.ndarray, np.ndarray]:
    """(N,) float64 flat mass (opacity × area of the flat face; 0 for a Gaussian that is not flat) and
    (N, 3) unit normals (the axis of the smallest scale)."""
    scales = scene.scales.astype(np.float64)
    order = np.argsort(scales, axis=1)
    s_min = np.take_along_axis(scales, order[:, :1], 1)[:, 0]
    s_mid = np.take_along_axis(scales, order[:, 1:2], 1)[:, 0]
    s_max = np.take_along_axis(scales, order[:, 2:], 1)[:, 0]
    flat = s_min < FLAT_RATIO * s_mid
    normal = np.take_along_axis(scene.rotation_matrices(), order[:, None, :1], 2)[:, :, 0]  # (N, 3) columns
    return scene.opacities.astype(np.float64) * s_mid * s_max * flat, normal


def _ground(scene: GaussianScene) -> UpGuess | None:
    """The up direction a ground of flat Gaussians shows (step 1 of :func:`guess_up`), or None."""
    mass, normal = _flat_mass(scene)
    total = float(mass.sum())
    if total <= 0:
        return None
    lo, hi = robust_box(scene)
    scores = {}
    for label in UP_AXES:
        a = "xyz".index(label[1])
        t = (scene.means[:, a] - lo[a]) / max(hi[a] - lo[a], 1e-12)  # 0 at the low end of the box
        bottom = t < GROUND_BAND if label[0] == "+" else t > 1.0 - GROUND_BAND
        scores[label] = float((mass * normal[:, a] ** 2 * bottom).sum()) / total
    weighted = {k: v * (CONVENTION_BONUS if k == "-y" else 1.0) for k, v in scores.items()}
    best = max(weighted, key=weighted.get)
    runner = max((k for k in scores if k != best), key=weighted.get)
    if scores[best] < MIN_GROUND_SHARE or weighted[best] < DOMINANCE * weighted[runner]:
        return None
    side = ("high " if best[0] == "-" else "low ") + best[1]
    a = "xyz".index(best[1])
    t = (scene.means[:, a] - lo[a]) / max(hi[a] - lo[a], 1e-12)
    face = (t < GROUND_BAND if best[0] == "+" else t > 1.0 - GROUND_BAND)
    share, centred = _carried(scene, a, mass * normal[:, a] ** 2 * face, ~face)
    if share < CARRIED_SHARE and not centred:
        top = ("-" if best[0] == "+" else "+") + best[1]
        return UpGuess(top, f"flat Gaussians lie as a face on the {side} side ({scores[best]:.0%} of the flat mass) "
                            f"that carries nothing ({share:.1%} of the rest over its middle, the rest off-centre): "
                            "the top of a scanned object, whose sides hang from its edges")
    return UpGuess(best, f"flat Gaussians lie as a ground on the {side} side: {scores[best]:.0%} of the flat mass, "
                         f"next {runner} {scores[runner]:.0%}")


def _carried(scene: GaussianScene, axis: int, face_mass: np.ndarray, rest: np.ndarray) -> tuple[float, bool]:
    """Whether a flat face carries the scene beyond it (``rest`` (N,) bool, weighed by
    :func:`framing_weights`): (the share of the rest over the face's middle, whether the rest's
    centre of mass is over it). The middle is the face's footprint (the 5–95 % extent of
    ``face_mass`` (N,) across ``axis``) less :data:`RIM` of it on every side. What stands on a
    ground stands over its middle, and a ground is under its object's centre of mass; the sides of
    a box hang from the edges of its top (a scan never sees the face an object rests on)."""
    w = framing_weights(scene) * rest
    if w.sum() <= 0 or face_mass.sum() <= 0:
        return 1.0, True
    over, centred = np.ones(scene.count, bool), True
    for b in (b for b in range(3) if b != axis):
        f_lo, f_hi = weighted_quantiles(scene.means[:, b], face_mass, [0.05, 0.95])
        lo, hi = f_lo + RIM * (f_hi - f_lo), f_hi - RIM * (f_hi - f_lo)
        over &= (scene.means[:, b] > lo) & (scene.means[:, b] < hi)
        centred &= bool(lo < float(w @ scene.means[:, b]) / float(w.sum()) < hi)
    return float(w[over].sum() / w.sum()), centred


def walled_axes(scene: GaussianScene, up: np.ndarray) -> list[int]:
    """The horizontal world axes (of ``up`` (3,)) with a wall at both ends, and an empty middle:
    the scene surrounds its robust centre (a room, a street between façades), so it is seen from
    inside. A wall is a plane of flat Gaussians facing along the axis in the outer :data:`GROUND_BAND`
    of the box at that end, holding ≥ :data:`WALL_SHARE` of the flat mass, its middle 80 % within
    :data:`WALL_THICKNESS` of the box's extent (a curved shell, a burger's side, is no wall). The
    middle is empty when < :data:`EMPTY_CORE` of the weight (:func:`framing_weights`) is within
    :data:`CORE` of the half-extent around the centre (an object fills its own middle)."""
    scene = _sample(scene)
    if scene.count == 0:
        return []
    lo, hi = robust_box(scene)
    size = np.maximum(hi - lo, 1e-12)
    w = framing_weights(scene)
    core = np.all(np.abs(scene.means - (lo + hi) / 2) < CORE * size / 2, axis=1)
    if w.sum() <= 0 or w[core].sum() >= EMPTY_CORE * w.sum():
        return []
    mass, normal = _flat_mass(scene)
    total = float(mass.sum())
    walled = []
    for a in range(3):
        if total <= 0 or abs(float(up[a])) > 0.5:  # not a horizontal axis
            continue
        t = (scene.means[:, a] - lo[a]) / size[a]
        for end in (t < GROUND_BAND, t > 1.0 - GROUND_BAND):
            m = mass * normal[:, a] ** 2 * end
            if m.sum() < WALL_SHARE * total:
                break
            p10, p90 = weighted_quantiles(t, m, [0.1, 0.9])
            if p90 - p10 > WALL_THICKNESS:
                break
        else:
            walled.append(a)
    return walled


def overview_camera(scene: GaussianScene, width: int, height: int, fov_deg: float = 50.0,
                    up: np.ndarray | None = None) -> Camera:
    """A camera looking at the scene's centre of mass (the mean of the Gaussians inside
    :func:`robust_box`, weighted as there), from ``ELEVATION_DEG`` above the horizon of ``up`` (default −y), at
    the distance where the box's corners fill ``FILL`` of the frame.

    A scene that surrounds its centre (:func:`walled_axes`: a room, a street) is seen from inside
    instead: level, along the box's longest horizontal axis, from :data:`INSIDE_BACK` of its
    half-length behind the centre, so that the first frame is the room, not the outside of its walls."""
    up = axis_vector("-y") if up is None else np.asarray(up, np.float64) / np.linalg.norm(up)
    lo, hi = robust_box(scene)
    centre = (lo + hi) / 2
    if walled_axes(scene, up):
        horizontal = [a for a in range(3) if abs(float(up[a])) <= 0.5]
        a = max(horizontal, key=lambda k: hi[k] - lo[k])
        along = np.eye(3)[a]
        eye = centre - INSIDE_BACK * (hi[a] - lo[a]) / 2 * along
        return look_at(eye, eye + along, width, height, fov_deg, up)
    scene = _sample(scene)
    if scene.count:
        inside = np.all((scene.means >= lo) & (scene.means <= hi), axis=1)
        w = framing_weights(scene)[inside]
        if w.sum() > 0:  # aim where the mass is: the box's middle may be empty space
            centre = (scene.means[inside] * w[:, None]).sum(0) / w.sum()
    # the horizontal direction looked along: the world axis furthest from up, made horizontal
    # (+z for y-up scenes, as COLMAP's first camera; +y for z-up ones, Blender's front view)
    ref = min((np.array([0.0, 0, 1]), np.array([0.0, 1, 0]), np.array([1.0, 0, 0])), key=lambda v: abs(v @ up))
    horizontal = ref - (ref @ up) * up
    horizontal /= np.linalg.norm(horizontal)
    e = math.radians(ELEVATION_DEG)
    fwd = math.cos(e) * horizontal - math.sin(e) * up
    probe = look_at(centre - fwd, centre, width, height, fov_deg, up)  # axes only; distance below
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]) - centre
    cam_axes = corners @ probe.R.T  # (8, 3): right, down, forward offsets from the centre
    tx = FILL * width / (2 * probe.fx)
    ty = FILL * height / (2 * probe.fy)
    dist = max(float(np.max(np.abs(cam_axes[:, 0]) / tx - cam_axes[:, 2])),
               float(np.max(np.abs(cam_axes[:, 1]) / ty - cam_axes[:, 2])),
               1.05 * float(np.max(-cam_axes[:, 2])), 1e-6)
    return look_at(centre - dist * fwd, centre, width, height, fov_deg, up)


def count_in_view(scene: GaussianScene, camera: Camera, near: float = 0.01) -> int:
    """How many Gaussians reach into ``camera``'s frustum (beyond ``near``, scene units), each taken
    as the sphere of 3 × its largest standard deviation: an upper bound of what the renderer draws,
    so 0 means the camera sees none of the scene."""
    if scene.count == 0:
        return 0
    t = camera.world_to_camera(scene.means)  # (N, 3): right, down, forward
    r = 3.0 * scene.scales.max(axis=1).astype(np.float64)
    w, h = camera.width, camera.height
    # inward normals of the four side planes through the centre and the image edges
    sides = np.array([[camera.fx, 0.0, camera.cx], [-camera.fx, 0.0, w - camera.cx],
                      [0.0, camera.fy, camera.cy], [0.0, -camera.fy, h - camera.cy]])
    sides /= np.linalg.norm(sides, axis=1, keepdims=True)
    inside = (t[:, 2] + r > near) & np.all(t @ sides.T > -r[:, None], axis=1)
    return int(np.count_nonzero(inside))


def rig_centre(cameras: list[Camera]) -> np.ndarray | None:
    """(3,) float64: the point nearest to all cameras' optical axes (least squares), or None when the
    axes are (nearly) parallel, as in a forward-facing capture, and no such point stands out."""
    if len(cameras) < 2:
        return None
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for cam in cameras:
        d = cam.forward / np.linalg.norm(cam.forward)
        P = np.eye(3) - np.outer(d, d)  # distance to the axis is |P (x − c)|
        A += P
        b += P @ cam.centre
    if np.linalg.eigvalsh(A / len(cameras))[0] < 1e-3:  # axes within ~2° of one another
        return None
    return np.linalg.solve(A, b)


def rig_up(cameras: list[Camera]) -> np.ndarray:
    """(3,) float64 unit world up: the mean of the cameras' image-up directions (−y rows)."""
    up = -np.mean([cam.R[1] for cam in cameras], axis=0)
    n = float(np.linalg.norm(up))
    return up / n if n > 1e-9 else -cameras[0].R[1]
