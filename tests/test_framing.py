"""Opening a scene without cameras: robust framing (floaters do not shrink the object), an up axis
guessed and said, and a focus found on every shared real scene."""

from __future__ import annotations

import json

import numpy as np
import pytest
from inria_folder import SCENES, TWO_PLANES

from dofview.cli import main
from dofview.frame import Frame
from dofview.framing import UP_AXES, axis_vector, guess_up, overview_camera, robust_box
from dofview.io import load_scene
from dofview.io.exr import read_exr
from dofview.rendering.focus import auto_focus, depth_range
from dofview.scene import GaussianScene, matrices_from_quats

SHARED = ["two_planes.ply", "burger.ply", "guitar.compressed.ply", "biker.spz", "tap.spz"]
SIZE = (160, 120)
MAX_CENTRE_OFFSET = 0.1  # the coverage's centroid within 10 % of the image size of its centre
MIN_SPAN = 0.5  # the object spans half the frame's width or height, not a dot among floaters


@pytest.mark.parametrize("name", SHARED)
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
    """two_planes: a ~0.8-unit object with floaters out to ±16 units."""
    scene = load_scene(TWO_PLANES, progress=False)
    lo, hi = robust_box(scene)
    assert np.all(hi - lo < 1.0)
    assert np.all(scene.means.max(0) - scene.means.min(0) > 10.0)  # the floaters are there


@pytest.mark.parametrize("name, expected", [("biker.spz", "-y"), ("burger.ply", "-y"), ("guitar.compressed.ply", "-y"),
                                            ("tap.spz", "-y"), ("two_planes.ply", "+x")])
def test_guessed_up(name, expected):
    """biker.spz and guitar are upright in −y (scenes README); burger's bun is on top in −y; the tap's
    hose hangs along +y; two_planes (a box standing on one flat face) stands on its low-x face."""
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
