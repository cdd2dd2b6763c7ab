"""Where to put the first camera: a scene's robust extent, its up axis, and the centre and up of
a set of training views.

Without cameras a scene is framed from its opacity-weighted percentile box (floaters and
near-transparent haze do not shrink the object to a dot), looked at slightly from above along the
world up that :func:`guess_up` finds. A place (a room, a corridor, a flat: a floor, a level ceiling
over it, surfaces around; or in the open air a ground with things standing around it under the sky;
:func:`find_place`) is seen from inside instead, from where a person would stand, at eye height,
along its long way. With cameras the orbit pivot is the point nearest to all
their optical axes and world up is their mean up.
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

CONVENTION_BONUS = 1.5  # −y's ground and y's room planes count this much more (the convention breaks near-ties)
DOMINANCE = 1.5  # a ground must be this many times stronger than the next side's
ELONGATION = 1.5  # without a ground, an axis this many times longer than the others is up (a standing figure)
FLAT_RATIO = 0.3  # a Gaussian is flat when its smallest scale is below this fraction of the middle one
GROUND_BAND = 0.25  # the ground is sought in this fraction of the box along each direction
MIN_GROUND_SHARE = 0.2  # below this share of the flat mass there is no ground to speak of
ROOM_PLANE_SHARE = 0.1  # a room's floor and ceiling each hold at least this share of the flat mass
RIM = 0.1  # a face's middle is its footprint less this fraction of it on every side
CARRIED_SHARE = 0.01  # a face with less of the rest over its middle (and not under its centre) carries nothing
PLACE_GRID = 128  # a place's grid has this many cells along its box's longer horizontal side (or its height)
PLACE_PAD = 0.1  # and reaches this fraction of the box beyond it on every side,
PLACE_PAD_UP = 0.5  # and this fraction of its height above and below it
OCCUPIED = 0.5  # a cell holds a surface when its Gaussians' opaque cross-section covers this share of its face
TOUCHED = 0.05  # and something (a floater) when this share; the eye keeps clear of both
EYE_HEIGHT = 0.55  # the eye stands this fraction of the way from floor to ceiling (1.4 m in a 2.6 m room)
LEVEL_SPAN = 0.15  # the floor is sought this fraction of the box height above the lowest surfaces seen
ROOFED = 0.5  # a place has a ceiling over at least this share of its free floor, level over this share
# of where one can stand (a dome, an object's top, the sky are not)
STOREY = 0.6  # a place's floor and ceiling span at least this share of its box's height (0.9–1 in rooms)
KNEE = 0.1  # of the room's height: the floor's tolerance, and where the space a body needs begins
LEVEL_TOLERANCE = 0.2  # of the room's height: a ceiling this near its level counts as level (coffers,
# a dropped ceiling, rooms of a flat a little higher or lower; a dome's sides come down further)
MIN_CLEARANCE = 0.1  # of the room's height: the eye's least distance to a wall or furniture (and 2 cells)
ENCLOSED = 0.6  # a place has surfaces in at least this share of the directions from the eye (doorways,
# windows and an open side let the others out: 0.7 in the shared corridor, kitchen and showroom)
SPHERE_RAYS = 256  # directions sampled over the sphere for that share
OPEN_SIDE = 120.0  # degrees: a place has no wider run of level directions that meet nothing from
# somewhere one can stand in it (a place lying on its side has the sky for a wall; an object on the
# ground is on one side of the eye); 0–35° in the rooms, the synthetic street and garden path
OPEN_SKY = 0.25  # in the open air, at least this share of the directions above the eye meet nothing (31–70 %
# in the roofless shared rooms, the synthetic garden path and street; 23 % at most inside the shared burger)
SHEET_NEIGHBOURS = 4  # a surface's cell has at least this many occupied neighbours (of 26); for that share,
# floaters are no walls
OPEN_ELEVATIONS = (0.0, 10.0, 20.0)  # in the open air, the share is of level directions and these
# elevations (degrees; the ground below and the sky above count for nothing either way)
AZIMUTHS = 72  # horizontal rays from the eye (5° apart) for what it sees at eye height
CANDIDATES = 16  # the clearest open spaces tried, in turn, for surfaces around them
FAN = math.radians(30.0)  # the side looked along is the one with the longer mean reach within this of the axis
STEP_BACK = 0.5  # the eye steps back this share of the free way behind it
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
    """Guess which world axis is up: a room's floor and ceiling, else the scene's ground, else the
    ground of a place in the open air, else its tall axis, else the convention.

    0. Room. A room, a corridor, a flat has flat planes at both ends of its up axis: the floor and
       the ceiling, each ≥ :data:`ROOM_PLANE_SHARE` of the flat mass facing along the axis in its
       outer quarter (corridor walls can match them: y's pair counts ×1.5, the convention), and
       :func:`find_place` finds somewhere to stand between them. Which plane is the floor the
       geometry does not tell reliably (a tiled floor may hold a quarter of a white ceiling's flat
       mass, and both have things under or over them), so the sign is the convention's: −y
       (3DGS/COLMAP), +z (Blender, z-up captures); along x, the plane with more flat mass is the floor.
    1. Ground. Trained scenes rest on something: a floor, a table, a ground plane, the flat base of
       an object. Those surfaces are fitted by flat Gaussians whose normal (the axis of the smallest
       scale) is along up, and they lie at the bottom of the scene. For each of the six axis
       directions d the score is the flat mass (opacity × area of the flat face) whose normal lies
       along d, among the Gaussians in the lowest quarter of the box along d, as a share of all
       flat mass (−y's counts ×1.5). A ground holds ≥ 20 % of the flat mass and ≥ 1.5× the next
       side's score, and carries the scene (:func:`_carried`); one that carries nothing is an
       object's top, the sides of a box hanging from its edges, and up points towards it.
    2. Open air. A roofless place (a garden path, a street, a courtyard, a room captured without
       its ceiling) may hold as much flat mass in its walls or façades as in its ground. Each side
       with ≥ 20 % of the flat mass and less than :data:`ROOM_PLANE_SHARE` at the other end of its
       axis (no ceiling over it) is tried as the ground, most flat mass first: the first from which
       :func:`find_place` finds a place in the open air is down.
    3. Tall axis. Without a ground (a figure, a statue, a guitar), a box ≥ 1.5× longer along one
       axis than along the others stands on it; the sign is the convention's (−y, +z, +x).
    4. Otherwise −y, the 3DGS/COLMAP convention.
    """
    if scene.count == 0:
        return UpGuess("-y", "empty scene: the 3DGS convention")
    sample = _sample(scene)
    ends = _end_shares(sample)
    room = _room(scene, ends)
    if room is not None:
        return room
    ground = _ground(sample, ends)
    if ground is not None:
        return ground
    open_air = _open_air(scene, ends)
    if open_air is not None:
        return open_air
    scene = sample
    lo, hi = robust_box(scene)
    size = hi - lo
    a = int(np.argmax(size))
    others = float(np.max(np.delete(size, a)))
    if size[a] >= ELONGATION * others:
        label = ("-y", "+z", "+x")[(1, 2, 0).index(a)]
        return UpGuess(label, f"no ground; the scene stands {size[a] / max(others, 1e-12):.1f}× taller along "
                              f"{'xyz'[a]} than across (sign by convention)")
    return UpGuess("-y", "no ground and no tall axis: the 3DGS convention")


def _room(scene: GaussianScene, ends: dict[str, float] | None) -> UpGuess | None:
    """The up of a room: flat planes at both ends of an axis (``ends``, :func:`_end_shares` of the
    scene's sample) and a place between them in ``scene`` (step 0 of :func:`guess_up`), or None."""
    if ends is None:
        return None
    ground = _open_ground(ends)
    # with a ground open to the sky on another axis, planes at both ends of this one are walls or
    # façades: a roofless room or a street, which the room test would take lying on its side
    pairs = sorted((a for a in "xyz" if min(ends["+" + a], ends["-" + a]) >= ROOM_PLANE_SHARE and ground in (None, a)),
                   key=lambda a: -min(ends["+" + a], ends["-" + a]) * (CONVENTION_BONUS if a == "y" else 1.0))
    for a in pairs:
        low, high = ends["+" + a], ends["-" + a]
        label = {"y": "-y", "z": "+z"}.get(a, "+x" if low >= high else "-x")
        place = find_place(scene, axis_vector(label))
        if place is not None and not place.open_air and place.open_side < OPEN_SIDE:
            return UpGuess(label, f"a room: flat planes at both ends of {a} ({low:.0%} and {high:.0%} of the flat "
                                  f"mass), a level ceiling over {place.roofed:.0%} of the free floor; the floor by "
                                  "convention")
    return None


def _open_air(scene: GaussianScene, ends: dict[str, float] | None) -> UpGuess | None:
    """The up of a place in the open air (step 2 of :func:`guess_up`; ``ends``: :func:`_end_shares`
    of the scene's sample), or None."""
    if ends is None:
        return None
    weighted = {k: v * (CONVENTION_BONUS if k == "-y" else 1.0) for k, v in ends.items()}
    for label in sorted(ends, key=lambda k: -weighted[k]):
        opposite = ("+" if label[0] == "-" else "-") + label[1]
        if ends[label] < MIN_GROUND_SHARE or ends[opposite] >= ROOM_PLANE_SHARE:
            continue
        place = find_place(scene, axis_vector(label))
        if place is not None and place.open_air:
            return UpGuess(label, f"a place in the open air: flat Gaussians lie as a ground on the "
                                  f"{'high' if label[0] == '-' else 'low'} {label[1]} side ({ends[label]:.0%} of "
                                  "the flat mass, nothing over it), with surfaces standing around")
    return None


def _open_ground(ends: dict[str, float]) -> str | None:
    """The axis ("x", "y" or "z") of a ground with nothing over it, from :func:`_end_shares`
    ``ends``: the ground test's winner (≥ :data:`MIN_GROUND_SHARE` of the flat mass, ≥
    :data:`DOMINANCE` times the next side's, −y's counting ×1.5) with less than
    :data:`ROOM_PLANE_SHARE` at the other end of its axis; None without one."""
    weighted = {k: v * (CONVENTION_BONUS if k == "-y" else 1.0) for k, v in ends.items()}
    best = max(weighted, key=weighted.get)
    runner = max((k for k in ends if k != best), key=weighted.get)
    opposite = ("+" if best[0] == "-" else "-") + best[1]
    if ends[best] < MIN_GROUND_SHARE or weighted[best] < DOMINANCE * weighted[runner] or ends[opposite] >= ROOM_PLANE_SHARE:
        return None
    return best[1]


def _end_shares(scene: GaussianScene) -> dict[str, float] | None:
    """For each label of :data:`UP_AXES`, the flat mass facing along its axis in the outer
    :data:`GROUND_BAND` of the box at the end a ground would be for that up ("+y": the low-y end), as
    a share of all flat mass; None without flat Gaussians."""
    mass, normal = _flat_mass(scene)
    total = float(mass.sum())
    if total <= 0:
        return None
    lo, hi = robust_box(scene)
    shares = {}
    for label in UP_AXES:
        a = "xyz".index(label[1])
        t = (scene.means[:, a] - lo[a]) / max(hi[a] - lo[a], 1e-12)  # 0 at the low end of the box
        bottom = t < GROUND_BAND if label[0] == "+" else t > 1.0 - GROUND_BAND
        shares[label] = float((mass * normal[:, a] ** 2 * bottom).sum()) / total
    return shares


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


def _ground(scene: GaussianScene, scores: dict[str, float] | None) -> UpGuess | None:
    """The up direction a ground of flat Gaussians shows (step 1 of :func:`guess_up`; ``scores``:
    :func:`_end_shares` of ``scene``), or None."""
    if scores is None:
        return None
    weighted = {k: v * (CONVENTION_BONUS if k == "-y" else 1.0) for k, v in scores.items()}
    best = max(weighted, key=weighted.get)
    runner = max((k for k in scores if k != best), key=weighted.get)
    if scores[best] < MIN_GROUND_SHARE or weighted[best] < DOMINANCE * weighted[runner]:
        return None
    side = ("high " if best[0] == "-" else "low ") + best[1]
    mass, normal = _flat_mass(scene)
    lo, hi = robust_box(scene)
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
    box_lo, box_hi = robust_box(scene)
    for b in (b for b in range(3) if b != axis):
        f_lo, f_hi = weighted_quantiles(scene.means[:, b], face_mass, [0.05, 0.95])
        # within the scene's box: a capture's far backdrop (the street below a flat's windows) is
        # flat and vast, and would stretch the footprint far beyond what the face carries
        f_lo, f_hi = max(f_lo, box_lo[b]), min(f_hi, box_hi[b])
        lo, hi = f_lo + RIM * (f_hi - f_lo), f_hi - RIM * (f_hi - f_lo)
        over &= (scene.means[:, b] > lo) & (scene.means[:, b] < hi)
        centred &= bool(lo < float(w @ scene.means[:, b]) / float(w.sum()) < hi)
    return float(w[over].sum() / w.sum()), centred


@dataclass(frozen=True)
class Place:
    """A scene seen from inside (a room, a corridor, a flat): where a person would stand in it.

    Heights are along the world up given to :func:`find_place`, in scene units.

    Attributes:
        eye: (3,) float64 world position of the eye, :data:`EYE_HEIGHT` of the way from floor to ceiling.
        look: (3,) float64 unit horizontal direction looked along.
        floor, ceiling: heights of the floor and the ceiling over the free space; in the open air
            the ground and the height of what stands around (:func:`_open_top`).
        enclosure: share of the directions from the eye (a sphere of them; level ones and a little
            above in the open air, :data:`OPEN_ELEVATIONS`) that meet a surface.
        roofed: share of the floor one can stand on that has the ceiling (within
            :data:`LEVEL_TOLERANCE` of the room's height of its level) over it (0 in the open air).
        open_air: a place with no ceiling (a garden path, a street, a courtyard).
        open_side: degrees, the widest run of level directions that meet nothing from the clearest
            spot that has surfaces around it (the spot least open of those): under :data:`OPEN_SIDE` in a room.
        reason: the same, in words.
    """

    eye: np.ndarray
    look: np.ndarray
    floor: float
    ceiling: float
    enclosure: float
    roofed: float
    open_air: bool
    open_side: float
    reason: str


@dataclass(frozen=True)
class _Grid:
    """Cubic cells over a scene's box in a frame whose third axis is up: ``cover`` (X, Y, Z) float64,
    the share of each cell's cross-section that its Gaussians make opaque (may exceed 1); ``origin``
    (3,) the low corner in frame coordinates (``frame`` (3, 3), rows e1, e2, up), ``cell`` the side."""

    cover: np.ndarray
    origin: np.ndarray
    cell: float
    frame: np.ndarray

    @property
    def occupied(self) -> np.ndarray:
        """(X, Y, Z) bool: the cells that hold a surface (:data:`OCCUPIED`)."""
        return self.cover >= OCCUPIED

    def world(self, ij: np.ndarray, height: float) -> np.ndarray:
        """(3,) world point over the centre of column ``ij`` (2,) at ``height``."""
        p = self.origin[:2] + (np.asarray(ij, np.float64) + 0.5) * self.cell
        return p[0] * self.frame[0] + p[1] * self.frame[1] + height * self.frame[2]


def horizontal_frame(up: np.ndarray) -> np.ndarray:
    """(3, 3) float64 orthonormal rows (e1, e2, up): e1 is the world axis furthest from ``up`` (3,)
    made horizontal, e2 = up × e1, so an axis-aligned up keeps the other two world axes."""
    up = np.asarray(up, np.float64) / np.linalg.norm(up)
    ref = min(np.eye(3), key=lambda v: abs(float(v @ up)))
    e1 = ref - (ref @ up) * up
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(up, e1), up])


def _occupancy(scene: GaussianScene, frame: np.ndarray, stride: int) -> _Grid:
    """Where the surfaces are: each Gaussian's opacity-weighted cross-section (opacity × 2π σ₁σ₂ of
    its two largest axes, the integral of its α) spread over the cells it spans (a 3 × 3 set of
    points at 0, ±σ along those axes when it is larger than a cell), at most its opacity per point,
    summed per cell and divided by the cell's face; a sampled scene counts each Gaussian ``stride``
    times. The grid covers the weighted 2–98 % box (:func:`framing_weights`) in ``frame`` plus
    :data:`PLACE_PAD` of it on every side, :data:`PLACE_GRID` cells along its longer horizontal side."""
    q = scene.means.astype(np.float64) @ frame.T  # (N, 3): e1, e2, height
    w = framing_weights(scene)
    box = np.array([weighted_quantiles(q[:, a], w, [0.02, 0.98]) for a in range(3)])  # (3, 2)
    pad = PLACE_PAD * (box[:, 1] - box[:, 0])
    pad[2] = PLACE_PAD_UP * (box[2, 1] - box[2, 0])  # a double-height ceiling is in the 2 % cut off
    lo, hi = box[:, 0] - pad, box[:, 1] + pad
    scales = scene.scales.astype(np.float64)
    # cells no smaller than a typical splat's footprint (2σ of its largest axis): finer, the
    # surfaces of a real capture break up into holes between their Gaussians
    cell = max(float(np.max(hi[:2] - lo[:2])) / PLACE_GRID, float(hi[2] - lo[2]) / PLACE_GRID,
               2.0 * float(np.median(scales.max(axis=1))), 1e-12)
    dims = np.maximum(np.ceil((hi - lo) / cell).astype(np.int64), 1)
    order = np.argsort(scales, axis=1)
    s1 = np.take_along_axis(scales, order[:, 2:], 1)[:, 0]
    s2 = np.take_along_axis(scales, order[:, 1:2], 1)[:, 0]
    rot = scene.rotation_matrices()
    a1 = np.take_along_axis(rot, order[:, None, 2:], 2)[:, :, 0] @ frame.T  # (N, 3) largest axis, in frame
    a2 = np.take_along_axis(rot, order[:, None, 1:2], 2)[:, :, 0] @ frame.T
    opacity = scene.opacities.astype(np.float64)
    face = opacity * 2 * math.pi * s1 * s2 / cell**2  # cells' worth of opaque cross-section
    big = 2 * s1 > cell
    uv = np.array([(u, v) for u in (-1.0, 0.0, 1.0) for v in (-1.0, 0.0, 1.0)])  # (9, 2) steps of σ
    spread = (q[big, None, :] + uv[None, :, :1] * (s1[big, None] * a1[big])[:, None, :]
              + uv[None, :, 1:] * (s2[big, None] * a2[big])[:, None, :])  # (B, 9, 3)
    points = np.concatenate([q[~big], spread.reshape(-1, 3)])
    weights = np.concatenate([np.minimum(face[~big], opacity[~big]),
                              np.repeat(np.minimum(face[big] / 9, opacity[big]), 9)])
    idx = np.floor((points - lo) / cell).astype(np.int64)
    keep = np.all((idx >= 0) & (idx < dims), axis=1)
    flat = np.ravel_multi_index(tuple(idx[keep].T), tuple(dims))
    cover = np.bincount(flat, weights[keep] * stride, minlength=int(np.prod(dims)))
    return _Grid(cover.reshape(tuple(dims)), lo, cell, frame)


@dataclass(frozen=True)
class _Levels:
    """The heights of a place (cell indices k along up) and what the eye sees up and down there.

    floor: the floor (the ground in the open air).
    top: the ceiling in a room; in the open air the surroundings' height (:func:`_open_top`).
    roofed: a ceiling over the free floor (a room), or none (the open air).
    below, above: (X, Y) int per column the first surface below the eye (−1: none) and above it
        (Z: none).
    eye: the eye's layer.
    """

    floor: int
    top: int
    roofed: bool
    below: np.ndarray
    above: np.ndarray
    eye: int


def _seen(occ: np.ndarray, eye: int) -> tuple[np.ndarray, np.ndarray]:
    """(X, Y) per column of ``occ`` (X, Y, Z) bool the first occupied layer below ``eye`` (−1: none)
    and above it (Z: none)."""
    nz = occ.shape[2]
    k = np.arange(nz)
    return (np.where(occ[:, :, :eye], k[:eye], -1).max(axis=2),
            np.where(occ[:, :, eye + 1:], k[eye + 1:], nz).min(axis=2))


def _levels(occ: np.ndarray) -> _Levels | str:
    """Floor and ceiling (or the open air's surroundings) of the occupied cells ``occ`` (X, Y, Z)
    bool seen from the free space; or why there are none, in words.

    From a first eye level at :data:`EYE_HEIGHT` of the box, each column free there looks down and
    up. The floor is the commonest first surface below in the lowest part of those (from the 15th
    percentile up :data:`LEVEL_SPAN` of the box height: furniture tops stand higher, a glossy
    floor's reflections lie lower); the ceiling likewise from the 85th percentile down, where at
    least :data:`ROOFED` of the columns have one. Once more from the eye those levels give. Where
    the free floor has no ceiling over it the place, if it is one, is in the open air
    (:func:`_open_top` gives its height)."""
    nz = occ.shape[2]
    span = max(1, int(LEVEL_SPAN * nz / (1 + 2 * PLACE_PAD_UP)))
    eye = int(EYE_HEIGHT * nz)
    for step in range(2):
        below, above = _seen(occ, eye)
        free = ~occ[:, :, eye] & (below >= 0)
        roofed = free & (above < nz)
        if not free.any():
            return "no floor under free space"
        hist = np.bincount(below[free], minlength=nz)
        q15 = int(np.searchsorted(np.cumsum(hist), 0.15 * hist.sum()))
        floor = q15 + int(np.argmax(hist[q15:q15 + span + 1]))
        if roofed.sum() < ROOFED * free.sum():
            if step:
                return f"no ceiling over the free floor (over {roofed.sum() / free.sum():.0%} of it)"
            top = _open_top(occ, floor)
            if isinstance(top, str):
                return f"no ceiling over the free floor (over {roofed.sum() / free.sum():.0%} of it), and {top}"
            eye = int(round(floor + EYE_HEIGHT * (top - floor)))
            return _Levels(floor, top, False, *_seen(occ, eye), eye)
        hist = np.bincount(above[roofed], minlength=nz + 1)
        q85 = int(np.searchsorted(np.cumsum(hist), 0.85 * hist.sum()))
        ceiling = max(q85 - span, 0) + int(np.argmax(hist[max(q85 - span, 0):q85 + 1]))
        if ceiling - floor < 4:
            return "floor and ceiling less than 4 cells apart"
        eye = int(round(floor + EYE_HEIGHT * (ceiling - floor)))
    return _Levels(floor, ceiling, True, *_seen(occ, eye), eye)


def _open_top(occ: np.ndarray, floor: int) -> int | str:
    """The height (layer k) of what stands around a place in the open air (a garden path's hedges
    and trees, a street's façades, a room's walls where the capture left out its ceiling), in
    place of a ceiling: the median top of the columns of ``occ`` (X, Y, Z) bool that rise from the
    ``floor`` layer (occupied from two to four layers above it: the floor's own thickness left out);
    or why there is none, in words. The eye then stands at :data:`EYE_HEIGHT` of it, as in a room:
    without a ceiling nothing else in the capture gives the scale of a person."""
    nz = occ.shape[2]
    rising = occ[:, :, min(floor + 2, nz):min(floor + 4, nz)].any(axis=2)
    if not rising.any():
        return "nothing stands on the ground"
    tops = nz - 1 - np.argmax(occ[:, :, ::-1], axis=2)  # each column's highest occupied layer
    top = int(np.median(tops[rising]))
    if top - floor < 4:
        return "what stands on the ground is less than 4 cells high"
    return top


def _clearance(blocked: np.ndarray) -> np.ndarray:
    """(X, Y) float64: each cell's distance in cells (alternate 8- and 4-neighbour steps) to the
    nearest ``blocked`` (X, Y) cell or the grid's edge."""
    dist = np.zeros(blocked.shape)
    reached = blocked.copy()
    reached[[0, -1], :] = reached[:, [0, -1]] = True
    steps = 0
    while not reached.all():
        steps += 1
        grown = reached.copy()
        grown[1:] |= reached[:-1]
        grown[:-1] |= reached[1:]
        grown[:, 1:] |= grown[:, :-1] if steps % 2 else reached[:, :-1]  # 8- then 4-neighbour steps:
        grown[:, :-1] |= grown[:, 1:] if steps % 2 else reached[:, 1:]  # an octagon, near a circle
        dist[grown & ~reached] = steps
        reached = grown
    return dist


def _march(hit: np.ndarray, starts: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rays through a boolean grid ``hit`` (2-D or 3-D) from each of ``starts`` (M, D) in cell units
    along each unit direction of ``dirs`` (K, D), in half-cell steps: (M, K) distances in cells to the
    first ``hit`` cell, or to where the ray leaves the grid, and (M, K) bool whether it met one."""
    dims = np.array(hit.shape)
    dist = np.zeros((len(starts), len(dirs)))
    met = np.zeros(dist.shape, bool)
    going = np.ones(dist.shape, bool)
    for n in range(1, int(2 * np.linalg.norm(dims)) + 2):
        cells = np.floor(starts[:, None, :] + 0.5 * n * dirs[None, :, :]).astype(np.int64)
        inside = np.all((cells >= 0) & (cells < dims), axis=2)
        dist[going & ~inside] = 0.5 * n
        going &= inside
        now = going.copy()
        now[going] = hit[tuple(cells[going].T)]
        dist[now] = 0.5 * n
        met |= now
        going &= ~now
        if not going.any():
            break
    return dist, met


def _sealed(occupied: np.ndarray) -> np.ndarray:
    """``occupied`` (X, Y, Z) grown by one cell along each axis: a ray in half-cell steps then
    cannot slip between two surface cells that touch at a corner, nor through a one-cell hole in a
    wall between a capture's Gaussians."""
    sealed = occupied.copy()
    for axis in range(3):
        grown = sealed.copy()
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[axis], hi[axis] = slice(None, -1), slice(1, None)
        grown[tuple(hi)] |= sealed[tuple(lo)]
        grown[tuple(lo)] |= sealed[tuple(hi)]
        sealed = grown
    return sealed


def _sheets(occupied: np.ndarray) -> np.ndarray:
    """The cells of ``occupied`` (X, Y, Z) bool with at least :data:`SHEET_NEIGHBOURS` occupied
    neighbours of their 26: surfaces, which continue into their neighbours, without the specks a
    capture leaves in the air (a floater fills a cell or two on its own)."""
    padded = np.pad(occupied, 1).astype(np.int16)
    x, y, z = occupied.shape
    count = sum(padded[1 + i:1 + i + x, 1 + j:1 + j + y, 1 + k:1 + k + z]
                for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)) - occupied
    return occupied & (count >= SHEET_NEIGHBOURS)


def _sphere(n: int) -> np.ndarray:
    """(n, 3) unit vectors spread evenly over the sphere (a Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(1 - z**2)
    t = math.pi * (1 + math.sqrt(5)) * i
    return np.stack([r * np.cos(t), r * np.sin(t), z], axis=1)


def _band(azimuths: int, elevations: tuple[float, ...]) -> np.ndarray:
    """(len(elevations) · azimuths, 3) unit vectors (x, y, up) every 360°/``azimuths`` around at each
    of ``elevations`` (degrees above the horizon)."""
    a = np.arange(azimuths) * 2 * math.pi / azimuths
    return np.concatenate([np.stack([np.cos(a) * math.cos(math.radians(e)), np.sin(a) * math.cos(math.radians(e)),
                                     np.full(azimuths, math.sin(math.radians(e)))], axis=1) for e in elevations])


def _widest_gap(met: np.ndarray) -> np.ndarray:
    """(M,) float64 degrees: per row of ``met`` (M, K) bool (K directions evenly around a circle)
    the widest run of directions that meet nothing, wrapping around."""
    k = met.shape[1]
    widest = np.zeros(len(met))
    for i, row in enumerate(met):
        if not row.any():
            widest[i] = 360.0
            continue
        turned = np.roll(row, -int(np.argmax(row)))  # start on a met direction: no run wraps
        runs = np.diff(np.flatnonzero(np.concatenate([turned, [True]]))) - 1
        widest[i] = 360.0 * runs.max() / k
    return widest


def find_place(scene: GaussianScene, up: np.ndarray) -> Place | None:
    """:func:`judge_place`'s place, or None for an object."""
    place = judge_place(scene, up)
    return place if isinstance(place, Place) else None


def judge_place(scene: GaussianScene, up: np.ndarray) -> Place | str:
    """Where to stand in a scene that is a place (a room, a corridor, a flat; a garden path or a
    street in the open air), or why it is an object, in words.

    The scene's surfaces are voxelised in cubes (:func:`_occupancy`, up along ``up`` (3,)). A place
    has a floor under its free space and a ceiling over it (:func:`_levels`: an object has no ceiling
    over the space around it), the two spanning most of the scene's height (:data:`STOREY`: not two
    layers inside an object), the ceiling level over most of where one can stand (a hollow shell's
    dome is not), somewhere one can stand (a column whose first surface below the eye is the floor,
    nothing from knee to above the eye: not on a table, not in a wall) at least
    :data:`MIN_CLEARANCE` of the room's height from any obstacle, and surfaces around it: at least
    :data:`ENCLOSED` of the directions from the eye meet one (a doorway or a window lets a few
    through). The answer comes from the first test that fails, in that order.

    A place in the open air (a garden path, a street, a courtyard, a room captured without its
    ceiling) has no ceiling over its free floor; what stands on its ground gives its height in place
    of one (:func:`_open_top`), and the eye must stand under the open sky (nothing over its column,
    :data:`OPEN_SKY` of the directions above it open: not inside a hollow object), with surfaces in
    :data:`ENCLOSED` of the level directions and those up to 20° above (:data:`OPEN_ELEVATIONS`)
    and no side open wider than :data:`OPEN_SIDE` (an object on open ground stands on one side of
    the eye). The storey and level-ceiling tests are a room's.

    The eye stands where the floor is clearest (furthest from walls, furniture and floaters; the
    first of the :data:`CANDIDATES` clearest open spaces with surfaces around it), at
    :data:`EYE_HEIGHT` of the floor-to-ceiling height, looking level along the principal axis of
    what it sees at that height (its isovist: the room's long way), towards the side that reaches
    further; then steps back :data:`STEP_BACK` of the free way behind it (keeping
    :data:`MIN_CLEARANCE`), so that the first frame shows the room's length."""
    if scene.count == 0:
        return "no Gaussians"
    stride = -(-scene.count // SAMPLE)
    sample = _sample(scene)
    frame = horizontal_frame(up)
    grid = _occupancy(sample, frame, stride)
    occ = grid.occupied
    levels = _levels(occ)
    if isinstance(levels, str):
        return levels
    floor, ceiling, below, above, eye_k = levels.floor, levels.top, levels.below, levels.above, levels.eye
    height = ceiling - floor
    storey = height * (1 + 2 * PLACE_PAD_UP) / occ.shape[2]  # of the box's height
    if levels.roofed and storey < STOREY:
        return f"floor and ceiling span {storey:.0%} of the scene's height: storeys of an object"
    tol = max(1, int(round(KNEE * height)))
    body = occ[:, :, floor + tol + 1:min(eye_k + tol + 1, occ.shape[2])].any(axis=2)
    stand = ~body & (below >= 0) & (np.abs(below - floor) <= tol)
    if not stand.any():
        return "nowhere to stand on the floor"
    sealed = _sealed(occ)
    sight = sealed[:, :, eye_k]
    # keep the lens off any Gaussian at all, not only surfaces: a floater at the lens would take the focus
    touched = (grid.cover[:, :, max(eye_k - 1, 0):eye_k + 2] >= TOUCHED).any(axis=2)
    obstacles = ~stand | sight | touched
    clear = _clearance(obstacles)
    level = float(np.count_nonzero(stand & (np.abs(above - ceiling) <= LEVEL_TOLERANCE * height)))
    level /= float(np.count_nonzero(stand))
    need = max(2.0, MIN_CLEARANCE * height)
    if levels.roofed and level < ROOFED:
        return f"no level ceiling (over {level:.0%} of where one can stand)"
    if clear.max() < need:
        return f"no room to stand ({clear.max():.0f} cells from an obstacle at most, {need:.1f} needed)"
    room = stand & (clear >= need)
    if not levels.roofed:
        # under the open sky: a hollow object's inside (a burger's, between its bun and patties)
        # has room and surfaces around, but a roof over most of it
        room &= above >= occ.shape[2]
        if not room.any():
            return "no room to stand under the open sky"
    # the clearest places to stand, each the clearest of its open space (none within another's
    # clearance), clearest first; the eye takes the first with surfaces around it (a terrace's
    # clear strip may look out at nothing)
    cells = []
    for cell in np.argwhere(room)[np.argsort(-clear[room], kind="stable")]:
        if all(np.hypot(*(cell - other)) >= clear[tuple(other)] for other in cells):
            cells.append(cell)
            if len(cells) == CANDIDATES:
                break
    cells = np.array(cells)
    starts = np.column_stack([cells + 0.5, np.full(len(cells), eye_k + 0.5)])
    # in the open air the sky is open: what counts is what stands around, level and a little above
    _, met = _march(sealed, starts, _sphere(SPHERE_RAYS) if levels.roofed else _band(AZIMUTHS, OPEN_ELEVATIONS))
    enclosed = met.mean(axis=1) >= ENCLOSED
    if not enclosed.any():
        around = "directions" if levels.roofed else "level directions"
        return (f"{'' if levels.roofed else 'open to the sky, and '}no surfaces around (in "
                f"{met.mean(axis=1).max():.0%} of the {around} at most)")
    # a room has walls on every side; a place lying on its side (a street, or a roofless room, with
    # a façade or a wall taken for its floor) has the sky for one of them (guess_up asks), and in the
    # open air, an object on its ground (a table on a lawn) stands on one side of the eye only
    gaps = np.full(len(starts), 360.0)
    gaps[enclosed] = _widest_gap(_march(_sealed(_sheets(occ)), starts[enclosed], _band(AZIMUTHS, (0.0,)))[1])
    if not levels.roofed:
        enclosed &= gaps < OPEN_SIDE
        if not enclosed.any():
            return f"open to the sky, and open on one side ({gaps.min():.0f}° of level directions meet nothing)"
        # and the sky over the eye: inside a hollow object the columns may be open, the dome is not
        upward = _sphere(SPHERE_RAYS)
        sky = np.zeros(len(starts))
        sky[enclosed] = 1.0 - _march(sealed, starts[enclosed], upward[upward[:, 2] > 0])[1].mean(axis=1)
        enclosed &= sky >= OPEN_SKY
        if not enclosed.any():
            return f"under a roof: {sky.max():.0%} of the directions above the eye meet nothing, at most"
    open_side = float(gaps[enclosed].min())
    pick = int(np.argmax(enclosed))
    best, start, enclosure = cells[pick], starts[pick], float(met[pick].mean())
    dirs = _band(AZIMUTHS, (0.0,))[:, :2]
    reach = _march(sight, start[None, :2], dirs)[0][0]
    # principal axis of the isovist (the star polygon of the reaches about the eye): its central
    # second moment ∫∫ (x − c)(x − c)ᵀ dA, from ∫₀ᵈ r^(k+1) dr = d^(k+2)/(k+2) per ray
    area = float((reach**2 / 2).sum())
    centroid = (dirs * (reach**3 / 3)[:, None]).sum(axis=0) / area
    moments = (dirs[:, :, None] * dirs[:, None, :] * (reach**4 / 4)[:, None, None]).sum(axis=0)
    axis = np.linalg.eigh(moments - area * np.outer(centroid, centroid))[1][:, -1]
    fan = np.cos(FAN) < dirs @ axis
    if reach[fan].mean() < reach[np.cos(FAN) < -(dirs @ axis)].mean():
        axis = -axis
    behind, _ = _march(obstacles, start[None, :2], -axis[None])  # as far as one can stand
    back = max(0.0, min(STEP_BACK * float(behind[0, 0]), float(behind[0, 0]) - MIN_CLEARANCE * height))
    position = best - back * axis
    eye_height = grid.origin[2] + (floor + 0.5 + EYE_HEIGHT * height) * grid.cell
    eye = grid.world(position, eye_height)
    look = axis[0] * frame[0] + axis[1] * frame[1]
    h = grid.cell
    if levels.roofed:
        why = (f"a place: a level ceiling {height * h:.3g} over the floor above {level:.0%} of where one can stand, "
               f"surfaces in {enclosure:.0%} of the directions from the eye")
    else:
        why = (f"a place in the open air: no ceiling, what stands around {height * h:.3g} high, surfaces in "
               f"{enclosure:.0%} of the level directions from the eye")
    return Place(eye, look / np.linalg.norm(look), float(grid.origin[2] + (floor + 0.5) * h),
                 float(grid.origin[2] + (ceiling + 0.5) * h), enclosure, level if levels.roofed else 0.0,
                 not levels.roofed, open_side, why)


def overview_camera(scene: GaussianScene, width: int, height: int, fov_deg: float = 50.0,
                    up: np.ndarray | None = None) -> Camera:
    """A camera looking at the scene's centre of mass (the mean of the Gaussians inside
    :func:`robust_box`, weighted as there), from ``ELEVATION_DEG`` above the horizon of ``up`` (default −y), at
    the distance where the box's corners fill ``FILL`` of the frame.

    A place (:func:`find_place`: a room, a corridor, a flat) is seen from inside instead: from where one
    would stand in it, at eye height, level, along its long way, so that the first frame is the room,
    not the outside of its walls."""
    up = axis_vector("-y") if up is None else np.asarray(up, np.float64) / np.linalg.norm(up)
    place = find_place(scene, up)
    if place is not None:
        return look_at(place.eye, place.eye + place.look, width, height, fov_deg, up)
    lo, hi = robust_box(scene)
    centre = (lo + hi) / 2
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
