"""The interactive viewer in a real window under Xvfb, driven by its scripted mode.

One viewer run (module fixture) goes through a script on samples/cards.ply; the tests then check
what it captured and reported against the headless renderer. Skipped (with the reason) only where
the Xvfb binary is missing.
"""

from __future__ import annotations

import json
import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import psnr

from dofview.bench.synth import CARD_DEPTHS, CARDS
from dofview.camera import Camera
from dofview.frame import RenderSettings
from dofview.io.cameras import load_cameras_json
from dofview.io.png import read_png
from dofview.lens import Lens
from dofview.tonemap import Tonemap

ROOT = Path(__file__).resolve().parents[1]
CARDS_PLY = ROOT / "samples" / "cards.ply"
CARDS_CAMERAS = ROOT / "samples" / "cards_cameras.json"
LAMP_PLY = ROOT / "samples" / "lamp.ply"
WINDOW = (720, 480)
MIN_PSNR = 40.0


@pytest.fixture(scope="module")
def display():
    """A private Xvfb server; Xvfb picks a free display number itself (-displayfd)."""
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        pytest.skip("Xvfb is not installed (apt-get install xvfb, or scripts/setup.sh): the viewer needs a display")
    proc = subprocess.Popen([xvfb, "-displayfd", "1", "-screen", "0", "1280x800x24", "-nolisten", "tcp"],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        number = proc.stdout.readline().strip()
        if not number.isdigit():
            pytest.fail(f"Xvfb did not start (exit status {proc.poll()})")
        yield f":{number}"
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def run_viewer(args: list[str], env: dict[str, str], timeout: float = 240) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "dofview", "view", *map(str, args)], env=env, cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout)


def image_camera() -> Camera:
    """The camera the viewer shows view_000 with: the view fitted into the image left of the panel."""
    from dofview.viewer.controls import ViewControls
    from dofview.viewer.panel import PANEL_WIDTH

    view = load_cameras_json(CARDS_CAMERAS)[0]
    return ViewControls.from_camera(view, 5.0).camera(WINDOW[0] - PANEL_WIDTH, WINDOW[1])


def card_centre(name: str, camera: Camera) -> tuple[float, float]:
    x0, y0, x1, y1 = next(c for c in CARDS if c.name == name).pixel_box(camera)
    return (x0 + x1) / 2, (y0 + y1) / 2


@pytest.fixture(scope="module")
def session(display, tmp_path_factory):
    """Run one scripted viewer session and return (folder, reports by name)."""
    out = tmp_path_factory.mktemp("viewer")
    cam = image_camera()
    bad = out / "broken.ply"
    bad.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 3\nend_header\nnot numbers\n")
    near, mid, far = (card_centre(n, cam) for n in ("near", "mid", "far"))
    script = [
        # refinement off: this session holds the window's single pass to the headless render
        # (the refined stages have their own tests in test_progressive.py and test_viewer_model.py)
        {"do": "set", "lens_samples_max": 0},
        {"do": "frames", "n": 2},
        {"do": "report", "path": out / "start.json"},
        {"do": "set", "focus": 8.0, "aperture": 30.0, "ev": 0.5, "gamma": 2.0, "background": [0.1, 0.2, 0.3]},
        {"do": "capture", "path": out / "lens.png"},
        {"do": "report", "path": out / "lens.json"},
        {"do": "set", "focus_aid": True},
        {"do": "capture", "path": out / "aid.png"},
        {"do": "report", "path": out / "aid.json"},
        {"do": "set", "focus_aid": False, "smooth_focus": True},
        {"do": "click", "x": near[0], "y": near[1]},
        {"do": "report", "path": out / "pulling.json", "settle": False},
        {"do": "report", "path": out / "near.json"},
        {"do": "set", "smooth_focus": False},
        {"do": "click", "x": mid[0], "y": mid[1]},
        {"do": "report", "path": out / "mid.json"},
        {"do": "click", "x": far[0], "y": far[1]},
        {"do": "report", "path": out / "far.json"},
        {"do": "orbit", "dx": 40.0, "dy": 15.0},
        {"do": "capture", "path": out / "orbit.png"},
        {"do": "report", "path": out / "orbit.json"},
        {"do": "save", "path": out / "saved.exr", "png": True},
        {"do": "copy_command"},
        {"do": "report", "path": out / "copied.json"},
        {"do": "set", "physical": True, "fnumber": 1.4, "focal_mm": 50.0, "exposure_follows_aperture": True,
         "shutter_s": 0.5},
        {"do": "capture", "path": out / "physical.png"},
        {"do": "report", "path": out / "physical.json"},
        {"do": "set", "physical": False, "exposure_follows_aperture": False, "colour_space": "linear"},
        {"do": "capture", "path": out / "linear.png"},
        {"do": "report", "path": out / "linear.json"},
        {"do": "set", "colour_space": "srgb", "aperture": 60.0, "blades": 6, "blade_rotation": 30.0},
        {"do": "capture", "path": out / "blades.png"},
        {"do": "report", "path": out / "blades.json"},
        {"do": "set", "dof": "splat", "blades": 0, "blade_rotation": 0.0},
        {"do": "capture", "path": out / "splat.png"},
        {"do": "report", "path": out / "splat.json"},
        {"do": "open", "path": bad},
        {"do": "report", "path": out / "bad.json"},
        {"do": "screenshot", "path": out / "bad.png"},
        {"do": "open", "path": LAMP_PLY},
        {"do": "report", "path": out / "lamp.json"},
        {"do": "quit"},
    ]
    path = out / "script.json"
    path.write_text(json.dumps(script, default=str))
    env = {**os.environ, "DISPLAY": display}
    res = run_viewer([CARDS_PLY, "--cameras", CARDS_CAMERAS, "--width", WINDOW[0], "--height", WINDOW[1],
                      "--focus", "4", "--script", path], env)
    assert res.returncode == 0, res.stderr
    reports = {p.stem: json.loads(p.read_text()) for p in out.glob("*.json") if p.stem != "script"}
    return out, reports


def headless_display(report: dict, focus_aid: bool = False) -> np.ndarray:
    """The same view rendered by the headless QuadBackend and tonemapped by display_image."""
    from dofview.io import load_scene
    from dofview.rendering.quad import QuadBackend

    c = report["camera"]
    camera = Camera(c["width"], c["height"], c["fx"], c["fy"], c["cx"], c["cy"], np.array(c["R"]), np.array(c["T"]))
    scene = load_scene(report["scene"], progress=False)
    scene.colour_space = report["colour_space"]
    renderer = QuadBackend(scene)
    renderer.draw(camera, Lens(**report["lens"]), RenderSettings(**report["render"]))
    t = report["tonemap"]
    image = renderer.display_image(Tonemap(t["exposure"], t["gamma"], tuple(t["background"])), focus_aid)
    renderer.release()
    return image


def test_viewer_starts_on_the_chosen_view(session):
    _, r = session
    cam = image_camera()
    got = r["start"]["camera"]
    assert (got["width"], got["height"]) == (cam.width, cam.height)
    assert got["fx"] == pytest.approx(cam.fx) and np.allclose(got["R"], cam.R) and np.allclose(got["T"], cam.T)
    assert r["start"]["lens"]["focus"] == 4.0 and r["start"]["drawn"] > 0
    assert r["start"]["total"] == r["start"]["count"]


@pytest.mark.parametrize("name, focus_aid", [("lens", False), ("aid", True), ("orbit", False), ("physical", False),
                                             ("linear", False), ("blades", False), ("splat", False)])
def test_window_matches_headless_render(session, name, focus_aid):
    """The image area read back from the window equals the headless render of the same parameters."""
    out, r = session
    shown = read_png(out / f"{name}.png")
    expected = headless_display(r[name], focus_aid)
    assert shown.shape == expected.shape
    assert psnr(shown, expected, 255.0) >= MIN_PSNR


def test_status_times_are_parts_of_one_frame(session):
    """Every report of the session (several right after a lens change, which draws): the status
    shows the last complete frame and the pass drawn in it, named, from one clock, so the part
    never exceeds the whole (it showed 'frame 637.8 ms splat 725.6 ms': one frame's splat beside
    the frame before it), and a frame that kept the image says so."""
    _, r = session
    drew = 0
    for name, report in r.items():
        t = report["times"]
        assert 0.0 < t["frame_ms"] and 0.0 <= t["render_ms"] <= t["frame_ms"], (name, t)
        part = f"{t['render']} {t['render_ms']:.1f} ms" if t["render"] else "image kept"
        assert t["status"].startswith(f"frame {t['frame_ms']:.1f} ms ({part})"), (name, t)
        assert (t["render_ms"] > 0) == bool(t["render"]), (name, t)
        drew += t["render_ms"] > 0
    assert drew > 0  # some reports follow a frame that drew


def test_blur_method_and_blades_reach_the_renderer(session):
    """The panel's "blur method" and "aperture blades" (script "set" as the panel sets them): the
    depth-layer default, a hexagon, then the per-splat method."""
    _, r = session
    assert r["lens"]["render"]["dof"] == "sliced"
    assert r["blades"]["render"]["blades"] == 6 and r["blades"]["render"]["blade_rotation"] == 30.0
    assert r["splat"]["render"]["dof"] == "splat"


def test_physical_lens_and_exposure_from_aperture(session):
    from dofview.lens import PhysicalLens

    _, r = session
    p = r["physical"]
    lens = PhysicalLens(50.0, 1.4).lens(p["camera"]["fx"], p["lens"]["focus"])
    assert p["lens"]["aperture"] == pytest.approx(lens.aperture)
    assert 2.0 ** p["tonemap"]["exposure"] == pytest.approx(2 ** 0.5 * 0.5 / 1.4 ** 2)  # EV stops
    assert r["linear"]["colour_space"] == "linear" and r["linear"]["tonemap"]["exposure"] == pytest.approx(0.5)


def test_focus_aid_tints_the_image(session):
    out, _ = session
    plain, aid = read_png(out / "lens.png").astype(int), read_png(out / "aid.png").astype(int)
    green = (aid[..., 1] - plain[..., 1]) > 20
    assert 0.01 < green.mean() < 0.9  # a band is tinted, not everything


@pytest.mark.parametrize("card", ["near", "mid", "far"])
def test_click_to_focus_lands_on_the_card(session, card):
    _, r = session
    assert r[card]["lens"]["focus"] == pytest.approx(CARD_DEPTHS[card], rel=0.05)


def test_smooth_focus_pull_eases(session):
    """A smooth click starts a pull from 8 towards the card (the easing itself: test_viewer_controls)."""
    _, r = session
    during, end = r["pulling"], r["near"]["lens"]["focus"]
    assert r["aid"]["lens"]["focus"] == 8.0
    assert during["focus_pull_target"] == end
    assert end < during["lens"]["focus"] <= 8.0
    assert r["near"]["focus_pull_target"] is None


def test_lens_and_exposure_changes_do_not_sort(session):
    _, r = session
    assert r["lens"]["sort_requests"] == r["start"]["sort_requests"] == r["far"]["sort_requests"]
    assert r["orbit"]["sort_requests"] > r["far"]["sort_requests"]
    # the focus aid is a tonemap change only: no new splatting pass
    assert r["aid"]["splat_draws"] == r["lens"]["splat_draws"]


def test_save_writes_what_dofview_render_writes(session, tmp_path):
    from dofview.cli import main
    from dofview.io.exr import read_exr

    out, r = session
    channels, header = read_exr(out / "saved.exr")
    assert (out / "saved.png").is_file()
    assert psnr(read_png(out / "saved.png"), read_png(out / "orbit.png"), 255.0) >= MIN_PSNR
    # the copied command re-renders the same view headless, to the same EXR
    command = r["copied"]["clipboard"]
    assert command == r["copied"]["command"] and command.startswith("dofview render ")
    argv = shlex.split(command)[1:]
    argv[argv.index("-o") + 1] = str(tmp_path / "again.exr")
    assert main(argv) == 0
    again, header2 = read_exr(tmp_path / "again.exr")
    assert set(header2) >= {k for k in header if k.startswith("dofview:")}
    assert json.loads(header["dofview:lens"])["focus"] == pytest.approx(json.loads(header2["dofview:lens"])["focus"])
    rgba = np.stack([channels[c] for c in "RGBA"], -1)
    rgba2 = np.stack([again[c] for c in "RGBA"], -1)
    assert psnr(rgba, rgba2, max(1.0, float(rgba.max()))) >= MIN_PSNR


def test_bad_file_keeps_the_scene_and_shows_the_error(session):
    _, r = session
    bad = r["bad"]
    assert "broken.ply" in bad["error"]
    assert bad["scene"] == str(CARDS_PLY) and bad["count"] == r["start"]["count"]
    assert bad["generation"] == r["start"]["generation"]


def test_opens_another_scene(session):
    _, r = session
    lamp = r["lamp"]
    assert lamp["scene"] == str(LAMP_PLY) and lamp["colour_space"] == "linear" and lamp["error"] == ""
    assert lamp["generation"] == r["start"]["generation"] + 1 and lamp["drawn"] > 0


def test_no_display_is_one_line_and_exit_2():
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    res = run_viewer([CARDS_PLY], env, timeout=60)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("dofview: error: no display (") and "use dofview render" in lines[0]


def test_bad_script_is_one_line_and_exit_2(display, tmp_path):
    script = tmp_path / "bad.json"
    script.write_text(json.dumps([{"do": "dance"}]))
    res = run_viewer([CARDS_PLY, "--script", script], {**os.environ, "DISPLAY": display}, timeout=60)
    assert res.returncode == 2
    assert res.stderr.strip().startswith(f"dofview: error: {script}: action 0") and "\n" not in res.stderr.strip()


def test_mouse_and_keys(display, tmp_path):
    """Raw input through ImGui's queue (what glfw's callbacks feed): click, drag, scroll and keys."""
    cam = image_camera()
    mid = card_centre("mid", cam)  # window units = pixels under Xvfb
    press = [{"do": "mouse_button", "button": 0, "down": True}]
    release = [{"do": "mouse_button", "button": 0, "down": False}]

    def key(name):
        return [{"do": "key", "key": name, "down": True}, {"do": "key", "key": name, "down": False}]

    def report(name, settle=True):
        return [{"do": "report", "path": tmp_path / f"{name}.json", "settle": settle}]

    script = (
        [{"do": "set", "smooth_focus": False}, {"do": "mouse_move", "x": mid[0], "y": mid[1]}, {"do": "frames", "n": 1}]
        + press + release + report("clicked")
        + press + [{"do": "mouse_move", "x": mid[0] + 30, "y": mid[1] + 10}] + release + report("dragged")
        + [{"do": "scroll", "steps": 2}] + report("scrolled")
        + key("h") + key("g") + report("keys")
        + key("tab") + [{"do": "key", "key": "w", "down": True}, {"do": "wait", "seconds": 0.2},
                        {"do": "key", "key": "w", "down": False}] + report("flown")
        + key("n") + report("next") + key("r") + report("reset")
    )
    path = tmp_path / "script.json"
    path.write_text(json.dumps(script, default=str))
    res = run_viewer([CARDS_PLY, "--cameras", CARDS_CAMERAS, "--width", WINDOW[0], "--height", WINDOW[1],
                      "--focus", "8", "--script", path], {**os.environ, "DISPLAY": display})
    assert res.returncode == 0, res.stderr
    r = {p.stem: json.loads(p.read_text()) for p in tmp_path.glob("*.json") if p.stem != "script"}
    assert r["clicked"]["lens"]["focus"] == pytest.approx(CARD_DEPTHS["mid"], rel=0.05)
    assert r["clicked"]["camera"]["T"] == pytest.approx(cam.T.tolist())  # a click is not a drag
    # the drag orbits: the camera moves, the pivot stays
    assert not np.allclose(r["dragged"]["camera"]["T"], r["clicked"]["camera"]["T"])
    assert np.allclose(r["dragged"]["pivot"], r["clicked"]["pivot"])
    # scrolling dollies towards the pivot
    def distance(rep):
        c = rep["camera"]
        return np.linalg.norm(-np.array(c["R"]).T @ np.array(c["T"]) - np.array(rep["pivot"]))
    assert distance(r["scrolled"]) == pytest.approx(distance(r["dragged"]) * 0.85 ** 2)
    assert r["keys"]["show_help"] and r["keys"]["focus_aid"]
    assert r["flown"]["fly_mode"]
    before, after = (np.array(-np.array(x["camera"]["R"]).T @ np.array(x["camera"]["T"])) for x in (r["keys"], r["flown"]))
    forward = np.array(r["keys"]["camera"]["R"])[2]
    assert np.dot(after - before, forward) > 0 and np.linalg.norm(np.cross(after - before, forward)) < 1e-6
    assert r["next"]["camera"]["name"] == "view_001"
    assert r["reset"]["camera"]["name"] == "" and r["reset"]["camera"]["T"] != r["next"]["camera"]["T"]


def test_compute_backend_sorts_on_the_gpu_without_the_sort_thread(display, tmp_path):
    """--raster compute: an orbit sends no view to the CPU sort thread, and the window shows the
    orbited view as the headless quad renderer draws it."""
    script = [{"do": "frames", "n": 2}, {"do": "report", "path": tmp_path / "start.json"},
              {"do": "set", "aperture": 30.0}, {"do": "orbit", "dx": 40.0, "dy": 15.0},
              {"do": "capture", "path": tmp_path / "orbit.png"}, {"do": "report", "path": tmp_path / "orbit.json"},
              {"do": "quit"}]
    path = tmp_path / "script.json"
    path.write_text(json.dumps(script, default=str))
    res = run_viewer([CARDS_PLY, "--cameras", CARDS_CAMERAS, "--width", WINDOW[0], "--height", WINDOW[1],
                      "--focus", "4", "--raster", "compute", "--script", path], {**os.environ, "DISPLAY": display})
    assert res.returncode == 0, res.stderr
    start, orbit = (json.loads((tmp_path / f"{n}.json").read_text()) for n in ("start", "orbit"))
    assert start["sort_requests"] == orbit["sort_requests"] == 0
    assert orbit["camera"]["R"] != start["camera"]["R"]
    assert psnr(read_png(tmp_path / "orbit.png"), headless_display(orbit), 255.0) >= MIN_PSNR
