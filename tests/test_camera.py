import numpy as np
import pytest

from dofview.camera import Camera, look_at
from dofview.errors import DofviewError
from dofview.io.cameras import load_cameras_json, save_cameras_json, select_camera


def test_look_at_projects_target_to_centre_and_keeps_image_up():
    cam = look_at([1.0, -2.0, -3.0], [0.5, 0.0, 4.0], 200, 100, 60)
    np.testing.assert_allclose(cam.project(np.array([[0.5, 0.0, 4.0]]))[0], [100, 50], atol=1e-9)
    np.testing.assert_allclose(cam.R @ cam.R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(cam.R) == pytest.approx(1.0)
    # world −y is "up" (OpenCV/COLMAP): a point above the target lands above the image centre
    above = cam.project(np.array([[0.5, -1.0, 4.0]]))[0]
    assert above[1] < 50


def test_cameras_json_round_trip_and_selection(tmp_path):
    cams = [look_at([i, 0, -5], [0, 0, 0], 320, 240, 40 + i) for i in range(3)]
    cams = [Camera(c.width, c.height, c.fx, c.fy, c.cx, c.cy, c.R, c.T, name=f"img{i}") for i, c in enumerate(cams)]
    path = tmp_path / "cameras.json"
    save_cameras_json(cams, path)
    back = load_cameras_json(path)
    for a, b in zip(cams, back):
        np.testing.assert_allclose(a.R, b.R, atol=1e-12)
        np.testing.assert_allclose(a.T, b.T, atol=1e-12)
        assert (a.fx, a.fy, a.width, a.height) == (b.fx, b.fy, b.width, b.height)
    assert select_camera(back, "img2").name == "img2"
    assert select_camera(back, "1").name == "img1"
    with pytest.raises(DofviewError, match="out of range"):
        select_camera(back, "7")
    with pytest.raises(DofviewError, match="no camera named"):
        select_camera(back, "nope")


def test_resized_scales_intrinsics_together():
    cam = look_at([0, 0, -5], [0, 0, 0], 400, 300, 50)
    small = cam.resized(200, 150)
    assert (small.fx, small.fy, small.cx, small.cy) == pytest.approx((cam.fx / 2, cam.fy / 2, 100, 75))
    p = np.array([[0.3, -0.2, 1.0]])
    np.testing.assert_allclose(small.project(p), cam.project(p) / 2, atol=1e-9)


def test_lens_shift_keeps_focus_plane_fixed():
    cam = look_at([0, 0, 0], [0, 0, 1], 100, 100, 60)
    shifted = cam.lens_shifted(0.1, -0.05, focus=4.0)
    on_plane = np.array([[0.7, -0.4, 4.0]])
    np.testing.assert_allclose(shifted.project(on_plane), cam.project(on_plane), atol=1e-9)
    off = np.array([[0.0, 0.0, 2.0]])
    disp = np.linalg.norm(shifted.project(off) - cam.project(off))
    assert disp == pytest.approx(cam.fx * np.hypot(0.1, -0.05) * abs(1 / 2.0 - 1 / 4.0))


@pytest.mark.parametrize("text", ["", "{}", "[]", "[{\"id\": 0}]", "not json"])
def test_bad_cameras_json(tmp_path, text):
    p = tmp_path / "c.json"
    p.write_text(text)
    with pytest.raises(DofviewError, match=str(p)):
        load_cameras_json(p)
