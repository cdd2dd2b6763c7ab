"""Opening a scene without cameras: robust framing (floaters do not shrink the object), an up axis
guessed and said, and a focus found on every scene in tests/data."""

from __future__ import annotations

import json

import numpy as np
import pytest
from inria_folder import SCENES, TWO_PLANES

from dofview.bench.primitives import Parts, add_panel
from dofview.bench.synth import room_scene
from dofview.cli import main
from dofview.frame import Frame
from dofview.framing import UP_AXES, axis_vector, guess_up, overview_camera, robust_box, walled_axes
from dofview.io import load_scene
from dofview.io.exr import read_exr
from dofview.lens import Lens
from dofview.rendering.focus import auto_focus, depth_range
from dofview.scene import GaussianScene, matrices_from_quats

SCENE_FILES = ["two_planes.ply", "burger.ply", "guitar.compressed.ply", "biker.spz", "tap.spz"]
SIZE = (160, 120)
MAX_CENTRE_OFFSET = 0.1  # the coverage's centroid within 10 % of the image size of its centre
MIN_SPAN = 0.5  # the object spans half the frame's width or height, not a dot among floaters


@pytest.mark.parametrize("name", SCENE_FILES)
def test_no_camera_render_frames_the_object_and_focuses_on_it(name, tmp_path, capsys):
    path = SCENES / name
    out = tmp_path / "x.exr"
    assert main(["render", str(path), "-o", str(out), "--width", str(SIZE[0]), "--height", str(SIZE[1])]) == 0
    err = capsys.readouterr().err
    assert "up axis " in err and "(guessed: " in err  # the guess is said in one line
    channels, header = read_exr(out)
    a = channels["A"].astype(np.float64)
    ys, xs = np.mgrid[: SIZE[1], : SIZE[0]] + 0.5
    cx, cy = (a * xs).sum() / a.sum(), (a * ys).sum() / a.sum()  # the coverage's α-weighted centroid
    assert abs(cx / SIZE[0] - 0.5) <= MAX_CENTRE_OFFSET and abs(cy / SIZE[1] - 0.5) <= MAX_CENTRE_OFFSET
    ys, xs = np.nonzero(a > 0.5)
    span = max(np.ptp(np.percentile(xs, [2, 98])) / SIZE[0], np.ptp(np.percentile(ys, [2, 98])) / SIZE[1])
    assert span >= MIN_SPAN
    focus = json.loads(header["dofview:lens"])["focus"]
    near, far = np.percentile(channels["Z"][a > 0.5], [2, 98])
    assert near * 0.9 <= focus <= far * 1.1  # on the object, not in empty space


def test_floaters_do_not_shrink_the_object():
    """two_planes: a ~0.7-unit object with floaters out to ~16 units."""
    scene = load_scene(TWO_PLANES, progress=False)
    lo, hi = robust_box(scene)
    assert np.all(hi - lo < 1.0)
    assert np.all(scene.means.max(0) - scene.means.min(0) > 10.0)  # the floaters are there


@pytest.mark.parametrize("name, expected", [("biker.spz", "-y"), ("burger.ply", "-y"), ("guitar.compressed.ply", "-y"),
                                            ("tap.spz", "-y"), ("two_planes.ply", "-x")])
def test_guessed_up(name, expected):
    """biker.spz and guitar are upright in −y (scenes README); burger's bun is on top in −y; the tap's
    hose hangs along +y; two_planes' low-x face is a box's top, its side hanging from its edge (its
    text reads upright in −x: issue 22)."""
    guess = guess_up(load_scene(SCENES / name, progress=False))
    assert guess.label == expected, guess.reason


def test_up_option_overrides_the_guess(tmp_path, capsys):
    out = tmp_path / "x.exr"
    assert main(["render", str(TWO_PLANES), "-o", str(out), "--width", "64", "--height", "48", "--up=-y"]) == 0
    assert "guessed" not in capsys.readouterr().err
    cam = json.loads(read_exr(out)[1]["dofview:camera"])
    assert np.dot(-np.array(cam["R"])[1], [0, -1, 0]) > 0.9  # image-up within 25° of −y (the view looks down 20°)


@pytest.mark.parametrize("label", UP_AXES)
def test_overview_camera_keeps_up_upright_and_looks_down(label):
    scene = load_scene(TWO_PLANES, progress=False)
    cam = overview_camera(scene, 80, 60, up=axis_vector(label))
    up = axis_vector(label)
    assert np.dot(cam.R[0], up) == pytest.approx(0.0, abs=1e-9)  # no roll
    assert np.dot(cam.forward, up) == pytest.approx(-np.sin(np.radians(20.0)))  # 20° down


def _frame(alpha: np.ndarray, depth: np.ndarray) -> Frame:
    rgba = np.zeros((*alpha.shape, 4), np.float32)
    rgba[..., 3] = alpha
    return Frame(rgba, depth.astype(np.float32), True, depth.astype(np.float32))


def test_auto_focus_falls_back_to_the_nearest_covered_pixels():
    """A ring-shaped object: nothing under the centre, so the ring nearest to it decides."""
    ys, xs = np.mgrid[:60, :80] + 0.5
    r = np.hypot(xs - 40, ys - 30)
    alpha = ((r > 12) & (r < 16)).astype(np.float32) + 0.9 * (r > 26)
    depth = np.where(r < 20, 3.0, 9.0) * (alpha > 0)
    assert auto_focus(_frame(alpha, depth)) == pytest.approx(3.0)
    haze = _frame(np.full((60, 80), 0.1, np.float32), np.full((60, 80), 5.0))
    assert auto_focus(haze) == pytest.approx(5.0)  # only haze: still a focus
    assert auto_focus(_frame(np.zeros((60, 80), np.float32), np.zeros((60, 80)))) is None
    assert depth_range(_frame(alpha, depth)) == pytest.approx((3.0, 9.0))


def test_guess_follows_the_scene_when_it_is_turned_z_up():
    """burger turned so its −y (bun on top) becomes +z, as a Blender export would have it: the
    ground is found on the other axis, so the guess is evidence, not the −y default."""
    scene = load_scene(SCENES / "burger.ply", progress=False)
    R = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])  # x → x, y → −z, z → y: world −y goes to +z
    assert np.allclose(R @ [0, -1, 0], [0, 0, 1])
    w, x = np.cos(-np.pi / 4), np.sin(-np.pi / 4)  # R as a quaternion: −90° about x
    q = scene.unit_quats()
    turned = np.stack([w * q[:, 0] - x * q[:, 1], w * q[:, 1] + x * q[:, 0],
                       w * q[:, 2] - x * q[:, 3], w * q[:, 3] + x * q[:, 2]], 1)  # (w, x, 0, 0) ⊗ q
    assert np.allclose(matrices_from_quats(turned[:5]), R @ scene.rotation_matrices()[:5])
    z_up = GaussianScene(scene.means @ R.T, turned, scene.scales, scene.opacities, scene.sh_dc)
    assert guess_up(z_up).label == "+z"


# ---- issue 22: rooms seen from inside, a scanned object's top is no ground ----------------------------
def two_faces(side_at: float) -> GaussianScene:
    """A face 0.7 × 0.7 units facing x at the low-x end and a side 0.3 deep facing y at y = ``side_at``
    (0: hanging from the face's edge, the shape of the original two_planes capture: a box's top
    and the one side the scan saw; 0.35: standing over the face's middle, a card on a board)."""
    parts = Parts.empty()
    add_panel(parts, 0, 0.0, {1: (0.0, 0.7), 2: (0.0, 0.7)}, (0.9, 0.9, 0.9), 0.0125)
    add_panel(parts, 1, side_at, {0: (0.0, 0.3), 2: (0.0, 0.7)}, (0.8, 0.2, 0.2), 0.0125)
    return parts.build("srgb", "two_faces")


def test_a_room_is_seen_from_inside_along_its_length():
    room = room_scene()
    guess = guess_up(room)
    assert guess.label == "-y", guess.reason
    cam = overview_camera(room, *SIZE, up=guess.vector)
    lo, hi = robust_box(room)
    assert np.all(cam.centre > lo) and np.all(cam.centre < hi)  # inside, not outside the walls
    assert cam.forward @ [1.0, 0.0, 0.0] > 0.999  # level, along x, the room's longest horizontal axis
    assert -cam.R[1] @ guess.vector > 0.999  # upright
    from dofview.rendering.quad import QuadBackend
    renderer = QuadBackend(room)
    frame = renderer.render(cam, Lens(1.0, 0.0))
    renderer.release()
    assert frame.alpha.mean() > 0.95  # walls, floor and ceiling fill the frame
    r, g, b = frame.rgba[SIZE[1] // 2, SIZE[0] // 2, :3]
    assert g > 3 * r and r == pytest.approx(b, rel=0.05)  # the far wall (x = +4, green) is in the middle
    assert auto_focus(frame) == pytest.approx(4.0 - cam.centre[0], rel=0.05)


@pytest.mark.parametrize("name", SCENE_FILES)
def test_objects_are_still_seen_from_outside(name):
    scene = load_scene(SCENES / name, progress=False)
    cam = overview_camera(scene, *SIZE, up=guess_up(scene).vector)
    lo, hi = robust_box(scene)
    assert not (np.all(cam.centre > lo) and np.all(cam.centre < hi))
    assert walled_axes(scene, guess_up(scene).vector) == []


def test_the_top_of_a_scanned_box_is_no_ground():
    """two_planes (the original capture) opened upside down: its top face, at the low-x end with
    the side hanging from its edge, was taken for a ground (+x up). A face that carries nothing is
    the object's top: up is towards it."""
    guess = guess_up(two_faces(side_at=0.0))
    assert guess.label == "-x" and "carries nothing" in guess.reason, guess.reason
    guess = guess_up(two_faces(side_at=0.35))  # the side stands over the face's middle: it is a ground
    assert guess.label == "+x" and "ground" in guess.reason, guess.reason
