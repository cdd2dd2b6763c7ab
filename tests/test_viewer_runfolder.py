"""The viewer on Inria-style run folders built from tests/data's scenes, under Xvfb: it opens at
training view 0 showing what `dofview render FOLDER` renders, orbits around the rig's centre, starts
sharp, cycles the world up with U, and opens a run folder or a camera-less scene from the panel."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from conftest import psnr
from inria_folder import BURGER, TWO_PLANES, make_run_folder, ring_cameras
from test_viewer import ROOT, display, headless_display, run_viewer  # noqa: F401  (display: the Xvfb fixture)

from dofview.cli import main
from dofview.framing import rig_centre
from dofview.io.cameras import load_cameras_json
from dofview.io.exr import read_exr
from dofview.io.png import read_png
from dofview.viewer.panel import PANEL_WIDTH
from dofview.viewer.settings import START_COC_PX

IMAGE = (320, 240)  # the image left of the panel: view 0's 4:3 at twice its size
MIN_PSNR = 40.0


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("viewer_runs")
    return (make_run_folder(base / "two_planes", {7000: BURGER, 30000: TWO_PLANES}, ring_cameras(TWO_PLANES)),
            make_run_folder(base / "burger", {30000: BURGER}, ring_cameras(BURGER)))


@pytest.fixture(scope="module")
def session(display, runs, tmp_path_factory):  # noqa: F811
    out = tmp_path_factory.mktemp("viewer_run")
    run, other = runs

    def key(name):
        return [{"do": "key", "key": name, "down": True}, {"do": "key", "key": name, "down": False}]

    script = [
        {"do": "frames", "n": 2},
        {"do": "report", "path": out / "start.json"},
        {"do": "capture", "path": out / "start.png"},
        *key("u"), {"do": "report", "path": out / "up.json"},
        {"do": "open", "path": other}, {"do": "report", "path": out / "other.json"},
        {"do": "open", "path": TWO_PLANES}, {"do": "report", "path": out / "plain.json"},
        {"do": "capture", "path": out / "plain.png"},
        {"do": "quit"},
    ]
    path = out / "script.json"
    path.write_text(json.dumps(script, default=str))
    res = run_viewer([run, "--width", IMAGE[0] + PANEL_WIDTH, "--height", IMAGE[1], "--script", path],
                     {**os.environ, "DISPLAY": display})
    assert res.returncode == 0, res.stderr
    reports = {p.stem: json.loads(p.read_text()) for p in out.glob("*.json") if p.stem != "script"}
    return out, reports, res.stderr


def test_opens_at_view_0_with_its_field_of_view(session, runs):
    _, r, stderr = session
    run = runs[0]
    assert f"run folder {run}: iteration 30000 (of 7000, 30000); {run / 'cameras.json'}: 6 views" in stderr
    view0 = load_cameras_json(run / "cameras.json")[0]
    cam = r["start"]["camera"]
    assert cam["name"] == view0.name and r["start"]["view_index"] == 0 and r["start"]["views"] == 6
    assert (cam["width"], cam["height"]) == IMAGE
    assert cam["fx"] == pytest.approx(view0.fx * IMAGE[0] / view0.width)  # the same field of view, fitted
    assert np.allclose(cam["R"], view0.R) and np.allclose(cam["T"], view0.T)
    assert r["start"]["scene"] == str(run / "point_cloud" / "iteration_30000" / "point_cloud.ply")


def test_window_shows_what_dofview_render_of_the_folder_renders(session, runs, tmp_path):
    out, r, _ = session
    shown = read_png(out / "start.png")
    assert psnr(shown, headless_display(r["start"]), 255.0) >= MIN_PSNR  # the same lens, headless
    # and `dofview render FOLDER` (view 0, pinhole, focus auto) at the window's image size
    png = tmp_path / "view0.png"
    assert main(["render", str(runs[0]), "--width", str(IMAGE[0]), "-o", str(tmp_path / "view0.exr"),
                 "--png", str(png)]) == 0
    assert psnr(shown, read_png(png), 255.0) >= MIN_PSNR
    header = read_exr(tmp_path / "view0.exr")[1]
    assert json.loads(header["dofview:lens"])["focus"] == pytest.approx(r["start"]["lens"]["focus"], rel=1e-3)


def test_orbits_around_the_rig_centre_with_the_rig_up(session, runs):
    _, r, _ = session
    cams = load_cameras_json(runs[0] / "cameras.json")
    assert np.allclose(r["start"]["pivot"], rig_centre(cams), atol=1e-6)
    assert np.allclose(r["start"]["up"], [0, -1, 0], atol=1e-9)


def test_first_frame_is_sharp_and_sliders_follow_the_depths(session):
    _, r, _ = session
    start = r["start"]
    near, far = start["depth_span"]
    focus, aperture = start["lens"]["focus"], start["lens"]["aperture"]
    assert near <= focus <= far
    worst = max(abs(1 / near - 1 / focus), abs(1 / far - 1 / focus))
    assert 0 < aperture / 2 * worst <= START_COC_PX * 1.001  # every blur in view below half a pixel


def test_u_cycles_the_world_up_and_frames_from_it(session):
    _, r, _ = session
    up = r["up"]
    assert up["up_label"] == "+z" and up["up"] == [0.0, 0.0, 1.0] and up["view_index"] is None
    image_up = -np.array(up["camera"]["R"])[1]
    assert image_up @ np.array([0, 0, 1.0]) == pytest.approx(np.cos(np.radians(20.0)))


def test_opening_a_folder_takes_its_cameras_and_a_plain_scene_drops_them(session, runs):
    out, r, _ = session
    other = r["other"]
    assert other["scene"] == str(runs[1] / "point_cloud" / "iteration_30000" / "point_cloud.ply")
    assert other["views"] == 6 and other["view_index"] == 0 and other["camera"]["name"] == "DSC_0000"
    assert "cameras.json: 6 views" in other["message"] and other["error"] == ""
    plain = r["plain"]
    assert plain["scene"] == str(TWO_PLANES) and plain["views"] == 0 and plain["view_index"] is None
    assert plain["up_label"] == "-x" and "up -x (" in plain["message"]  # a box's top: issue 22
    alpha_shown = read_png(out / "plain.png").astype(float).sum(axis=2) > 30
    ys, xs = np.nonzero(alpha_shown)
    assert abs(xs.mean() / IMAGE[0] - 0.5) < 0.15 and abs(ys.mean() / IMAGE[1] - 0.5) < 0.15  # framed, not lost
