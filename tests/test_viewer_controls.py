"""The viewer's pure parts, without a window: camera controls, lens/image settings, focus pull,
the sort thread and the script checker."""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest
from conftest import random_scene

from dofview.camera import look_at
from dofview.errors import DofviewError
from dofview.lens import PhysicalLens
from dofview.rendering.depth_order import front_to_back
from dofview.rendering.sort_thread import SortThread
from dofview.viewer.controls import (
    MIN_POLE_ANGLE,
    ORBIT_RAD_PER_PX,
    ZOOM_PER_STEP,
    ViewControls,
    rotation,
)
from dofview.viewer.script import load_script
from dofview.viewer.settings import FOCUS_PULL_S, FocusPull, ViewerSettings


@pytest.fixture
def controls() -> ViewControls:
    cam = look_at((1.0, -2.0, -6.0), (0.0, 0.0, 0.0), 400, 300, 50.0)
    return ViewControls.from_camera(cam, pivot_distance=float(np.linalg.norm([1.0, -2.0, -6.0])))


def assert_rotation(R):
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-9) and np.linalg.det(R) == pytest.approx(1.0)


def test_from_camera_reproduces_the_camera():
    cam = look_at((0.5, 0.2, -3.0), (0.0, 0.0, 1.0), 640, 480, 60.0)
    c = ViewControls.from_camera(cam, 2.0).camera(640, 480)
    assert np.allclose(c.R, cam.R) and np.allclose(c.T, cam.T) and c.fx == pytest.approx(cam.fx)
    # another window shape still shows the whole reference frame: the focal length shrinks to fit
    wide = ViewControls.from_camera(cam, 2.0).camera(1280, 480)
    tall = ViewControls.from_camera(cam, 2.0).camera(640, 960)
    assert wide.fx == pytest.approx(cam.fx) and tall.fx == pytest.approx(cam.fx)
    assert ViewControls.from_camera(cam, 2.0).camera(320, 480).fx == pytest.approx(cam.fx / 2)


def test_orbit_keeps_the_pivot_centred_and_at_its_distance(controls):
    pivot = controls.pivot.copy()
    for dx, dy in [(40, 0), (0, 25), (-13, 7)]:
        controls.orbit(dx, dy)
        cam = controls.camera(400, 300)
        assert np.allclose(controls.pivot, pivot)
        assert np.linalg.norm(cam.centre - pivot) == pytest.approx(controls.pivot_distance)
        assert np.allclose(cam.project(pivot[None])[0], (200, 150))
        assert_rotation(cam.R)


def test_orbit_full_turn_returns(controls):
    start = controls.camera(400, 300)
    steps = 100
    for _ in range(steps):
        controls.orbit(2 * math.pi / ORBIT_RAD_PER_PX / steps, 0)
    end = controls.camera(400, 300)
    assert np.allclose(end.R, start.R, atol=1e-9) and np.allclose(end.T, start.T, atol=1e-9)


def test_orbit_directions(controls):
    """Dragging right swings the camera left around the pivot; dragging down raises it."""
    cam0 = controls.camera(400, 300)
    right, up = cam0.R[0], controls.up
    controls.orbit(50, 0)
    assert np.dot(controls.centre - cam0.centre, right) < 0
    c1 = controls.centre.copy()
    controls.orbit(0, 50)
    assert np.dot(controls.centre - c1, up) > 0


def test_orbit_never_flips_over_the_pole(controls):
    for _ in range(50):
        controls.orbit(0, 200)
        angle = math.acos(np.clip(np.dot(controls.R[2], controls.up), -1, 1))
        assert angle >= MIN_POLE_ANGLE - 1e-9 and angle <= math.pi - MIN_POLE_ANGLE + 1e-9
    assert np.dot(-controls.R[1], controls.up) > 0  # image-up still points up: no flip
    for _ in range(50):
        controls.orbit(0, -200)
        assert np.dot(-controls.R[1], controls.up) > 0


def test_pan_moves_the_pivot_plane_with_the_mouse(controls):
    cam0 = controls.camera(400, 300)
    pivot = controls.pivot.copy()
    controls.pan(30.0, -12.0, cam0.fx)
    cam1 = controls.camera(400, 300)
    assert np.allclose(cam1.project(pivot[None])[0], cam0.project(pivot[None])[0] + (30.0, -12.0))
    assert np.allclose(cam1.R, cam0.R)


def test_zoom_dollies_towards_the_pivot(controls):
    pivot, d = controls.pivot.copy(), controls.pivot_distance
    controls.zoom(3)
    assert controls.pivot_distance == pytest.approx(d * ZOOM_PER_STEP ** 3)
    assert np.allclose(controls.pivot, pivot)
    controls.zoom(-3)
    assert controls.pivot_distance == pytest.approx(d)


def test_fly_moves_along_camera_axes_at_the_given_speed(controls):
    R, c = controls.R.copy(), controls.centre.copy()
    controls.fly(0, 0, 1, 0.5)
    assert np.allclose(controls.centre - c, 0.5 * R[2])
    c = controls.centre.copy()
    controls.fly(1, 0, 1, 1.0)  # a diagonal is not faster
    assert np.linalg.norm(controls.centre - c) == pytest.approx(1.0)
    assert np.allclose(controls.R, R)


def test_look_turns_about_the_camera_centre(controls):
    c, R0 = controls.centre.copy(), controls.R.copy()
    controls.look(60, 0)  # mouse right: look right
    assert np.allclose(controls.centre, c)
    assert np.dot(controls.R[2] - R0[2], R0[0]) > 0.1
    controls.look(0, 60)  # mouse down: look down
    assert np.dot(controls.R[2], R0[1]) > 0.1
    assert_rotation(controls.R)


def test_rotation_is_rodrigues():
    R = rotation(np.array([0.0, 0.0, 1.0]), math.pi / 2)
    assert np.allclose(R @ [1.0, 0, 0], [0, 1.0, 0])


def test_focus_pull_eases_in_inverse_depth():
    pull = FocusPull()
    pull.start(8.0, 2.0, now=10.0)
    assert pull.active and pull.value(10.0) == pytest.approx(8.0)
    values = [pull.value(10.0 + t) for t in np.linspace(0, FOCUS_PULL_S * 0.999, 20)]
    assert all(a >= b for a, b in zip(values, values[1:]))  # monotone towards the target
    # half way in time is half way in 1/z (smoothstep(0.5) = 0.5)
    assert 1 / pull.value(10.0 + FOCUS_PULL_S / 2) == pytest.approx((1 / 8 + 1 / 2) / 2)
    assert pull.value(10.0 + FOCUS_PULL_S) == 2.0 and not pull.active


def test_settings_build_the_render_objects():
    s = ViewerSettings(focus=3.0, aperture=40.0)
    cam = look_at((0, 0, 0), (0, 0, 1), 800, 600, 60.0)
    assert s.lens(cam).aperture == 40.0 and s.lens(cam).focus == 3.0
    s.dof_enabled = False
    assert s.lens(cam).aperture == 0.0
    s.dof_enabled, s.physical = True, True
    expected = PhysicalLens(s.focal_mm, s.fnumber, s.sensor_mm, s.units_per_metre).strength(cam.fx, 3.0)
    assert s.lens(cam).aperture == pytest.approx(expected)
    s.ev = 1.0
    assert s.tonemap().multiplier == pytest.approx(2.0)
    s.exposure_follows_aperture, s.shutter_s = True, 0.5
    assert s.tonemap().multiplier == pytest.approx(2.0 * 0.5 / s.fnumber ** 2)
    s.fnumber *= 2  # one more f-number doubling: a quarter of the light
    assert s.tonemap().multiplier == pytest.approx(2.0 * 0.5 / s.fnumber ** 2)
    assert s.lens_request().to_dict()["fnumber"] == s.fnumber


def test_sort_thread_matches_front_to_back():
    scene = random_scene(n=3000)
    cams = [look_at((x, 0.3, -2.0), (0, 0, 5), 64, 48) for x in (-1.0, 0.0, 1.0)]
    sorter = SortThread()
    try:
        for cam in cams:  # later requests replace earlier ones still waiting
            sorter.request(scene.means, cam)
        deadline = time.monotonic() + 30.0
        while sorter.pending and time.monotonic() < deadline:
            time.sleep(0.01)
        res = sorter.result()
    finally:
        sorter.close()
    assert res is not None and res.view_key == cams[-1].view_key()
    assert np.array_equal(res.order, front_to_back(scene.means, cams[-1])[::-1])


def test_script_is_checked_up_front(tmp_path):
    good = tmp_path / "good.json"
    good.write_text(json.dumps([{"do": "set", "focus": 2, "tau": 0.0}, {"do": "quit"}]))
    assert len(load_script(good)) == 2
    for bad, words in [([{"do": "dance"}], "action 0"), ({"do": "quit"}, "JSON list"),
                       ([{"do": "set", "fokus": 2}], "fokus")]:
        path = tmp_path / "bad.json"
        path.write_text(json.dumps(bad))
        with pytest.raises(DofviewError, match=words):
            load_script(path)
    with pytest.raises(DofviewError, match="not a valid JSON"):
        (tmp_path / "x.json").write_text("[")
        load_script(tmp_path / "x.json")


@pytest.mark.parametrize("width", [390, 800])
def test_click_to_focus_depth_on_the_cards(width):
    """focus.depth_at on the renderer's frame (what a click uses) lands within 5% of each card's
    depth, headless.

    The cards' texel discs leave ~1-5% gaps onto the wall at depth 14, so the α-weighted mean
    depth is pulled several % (more at higher resolution); the α-weighted inverse depth is not.
    """
    from pathlib import Path

    from dofview.bench.synth import CARDS
    from dofview.io import load_scene
    from dofview.io.cameras import load_cameras_json
    from dofview.lens import Lens
    from dofview.rendering.focus import depth_at
    from dofview.rendering.quad import QuadBackend

    samples = Path(__file__).resolve().parents[1] / "samples"
    view = load_cameras_json(samples / "cards_cameras.json")[0]
    camera = view.resized(width, width * 3 // 4)
    renderer = QuadBackend(load_scene(samples / "cards.ply", progress=False))
    frame = renderer.render(camera, Lens(1.0, 0.0))
    for card in CARDS:
        x0, y0, x1, y1 = card.pixel_box(camera)
        for fx, fy in [(0.5, 0.5), (0.3, 0.7), (0.8, 0.2)]:
            depth = depth_at(frame, x0 + fx * (x1 - x0), y0 + fy * (y1 - y0))
            assert depth == pytest.approx(card.depth, rel=0.05)
    assert depth_at(frame, -50, -50) is None  # outside the image: nothing to focus on
    renderer.release()


def test_frame_times_show_one_frame_and_its_own_pass():
    """A long frame that draws, then short ones that keep the image: each status pairs a frame
    with the pass drawn in it, named (the old status paired this frame's splat with the last
    frame's length, kept a splat time on frames that drew none, and said 'splat 0.0 ms' beside a
    frame of thin-lens refinement)."""
    from dofview.viewer.timing import FrameTimes

    times = FrameTimes()
    times.begin(10.0)
    times.rendered("depth layers", 725.6)  # a slow full frame, within a frame of 0.75 s
    times.begin(10.75)
    assert (times.frame_ms, times.render_kind, times.render_ms) == pytest.approx((750.0, "depth layers", 725.6))
    assert times.status(12.0) == "frame 750.0 ms (depth layers 725.6 ms)\nlast sort 12.0 ms"
    times.rendered("thin-lens refinement", 1290.3)
    times.begin(12.1)
    assert times.status(12.0) == "frame 1350.0 ms (thin-lens refinement 1290.3 ms)\nlast sort 12.0 ms"
    times.begin(12.13)  # a frame that kept the image
    assert (times.frame_ms, times.render_kind, times.render_ms) == pytest.approx((30.0, "", 0.0))
    assert times.status(12.0) == "frame 30.0 ms (image kept)\nlast sort 12.0 ms"
    assert list(times.periods) == pytest.approx([750.0, 1350.0, 30.0])
