"""Adaptive tone mapping in the real viewer under Xvfb: the camera swings from the room to the lamp
of samples/lamp.ply with the histogram operator; the shown image adapts smoothly and the lock
freezes the adaptation. (Display fixture and runner from test_viewer.py.)"""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from test_viewer import LAMP_PLY, display, run_viewer  # noqa: F401  (display is a fixture)

from dofview.io.png import read_png

STEPS = 16
MIN_ADAPTATION_STOPS = 0.2
MIN_SHARE_AFTER = 0.5  # of the largest step: what the display still changes after it, in its direction


@pytest.fixture(scope="module")
def swing(display, tmp_path_factory):  # noqa: F811
    out = tmp_path_factory.mktemp("swing")
    script = [{"do": "frames", "n": 3}, {"do": "report", "path": out / "start.json"}]
    for i in range(STEPS):  # a 12-pixel turn per step, from the bare room towards the lamp
        script += [{"do": "look", "dx": 12, "dy": 0},
                   {"do": "capture", "path": out / f"step{i:02d}.png", "settle": False}]
    script += [{"do": "settle"}, {"do": "set", "stats_lock": True},
               {"do": "report", "path": out / "adapted.json", "settle": False}]
    script += [{"do": "look", "dx": -48, "dy": 0} for _ in range(4)]
    script += [{"do": "wait", "seconds": 0.5}, {"do": "report", "path": out / "locked.json", "settle": False},
               {"do": "quit"}]
    (out / "script.json").write_text(json.dumps(script, default=str))
    res = run_viewer([LAMP_PLY, "--eye=0,0,0", "--target=-2,0.3,4.5", "--width", 560, "--height", 300,
                      "--focus", 3, "--tonemap", "histogram", "--script", out / "script.json"],
                     {**os.environ, "DISPLAY": display})
    assert res.returncode == 0, res.stderr
    return out


def _mean_luminance(path) -> float:
    img = (read_png(path).astype(np.float64) / 255.0) ** 2.2
    return float((img @ np.array([0.2126, 0.7152, 0.0722])).mean())


def test_adaptation_is_smooth_over_the_swing(swing):
    """The lamp coming into view makes the room low-key: the mean display luminance falls. Smoothed
    statistics spread that over frames — the largest step (1 − e^(−Δt/t0) of the change; llvmpipe
    frames take ~0.3 s) is followed by steps the same way that add up to at least MIN_SHARE_AFTER
    of it — where a per-frame adaptation would cut in one step."""
    means = np.array([_mean_luminance(swing / f"step{i:02d}.png") for i in range(STEPS)])
    steps = np.diff(means)
    k = int(np.argmax(np.abs(steps)))
    after = steps[k + 1:k + 4]
    assert len(after) == 3 and (np.sign(after) == np.sign(steps[k])).all(), steps
    assert abs(steps[k + 1:].sum()) >= MIN_SHARE_AFTER * abs(steps[k]), steps
    start = json.loads((swing / "start.json").read_text())["tonemap"]
    adapted = json.loads((swing / "adapted.json").read_text())["tonemap"]
    assert start["operator"] == "histogram" and start["stats"] is not None
    assert abs(adapted["stats"]["key_log2"] - start["stats"]["key_log2"]) >= MIN_ADAPTATION_STOPS


def test_lock_freezes_the_adaptation(swing):
    adapted = json.loads((swing / "adapted.json").read_text())["tonemap"]["stats"]
    locked = json.loads((swing / "locked.json").read_text())["tonemap"]
    assert locked["locked"] and locked["stats"] == adapted


def test_joint_statistics_are_pooled_over_the_views_and_locked(display, tmp_path):  # noqa: F811
    """--stats joint: the viewer shows the statistics pooled over every view of cameras.json (the
    same numbers as api.joint_stats headless) and does not adapt when the camera moves."""
    from test_viewer import ROOT

    from dofview.api import joint_stats
    from dofview.io import load_scene
    from dofview.io.cameras import load_cameras_json
    from dofview.rendering.quad import QuadBackend
    from dofview.tonemap import Reinhard05

    cameras = ROOT / "samples" / "lamp_cameras.json"
    script = [{"do": "frames", "n": 2}, {"do": "report", "path": tmp_path / "start.json", "settle": False},
              {"do": "look", "dx": 80, "dy": 0}, {"do": "wait", "seconds": 0.5},
              {"do": "report", "path": tmp_path / "moved.json", "settle": False}, {"do": "quit"}]
    (tmp_path / "script.json").write_text(json.dumps(script, default=str))
    res = run_viewer([LAMP_PLY, "--cameras", cameras, "--width", 480, "--height", 300, "--focus", 3,
                      "--tonemap", "reinhard05", "--stats", "joint", "--script", tmp_path / "script.json"],
                     {**os.environ, "DISPLAY": display})
    assert res.returncode == 0, res.stderr
    start, moved = (json.loads((tmp_path / f"{n}.json").read_text())["tonemap"] for n in ("start", "moved"))
    expected = joint_stats(QuadBackend(load_scene(LAMP_PLY)), load_cameras_json(cameras), Reinhard05())
    assert start["locked"] and start["stats"]["key_log2"] == pytest.approx(expected.key, abs=1e-9)
    assert start["stats"]["hi_log2"] == pytest.approx(expected.hi, abs=1e-9)
    assert moved["stats"] == start["stats"]


def test_scenes_open_with_their_colour_spaces_operator(display, tmp_path):  # noqa: F811
    """Without --tonemap (auto) the viewer shows an sRGB scene with clip and, opening a linear HDR
    one, switches to LINEAR_DEFAULT; a picked operator would stay (panel.py clears tonemap_auto)."""
    from test_viewer import CARDS_PLY

    from dofview.tonemap import LINEAR_DEFAULT

    script = [{"do": "frames", "n": 1}, {"do": "report", "path": tmp_path / "cards.json", "settle": False},
              {"do": "open", "path": LAMP_PLY}, {"do": "frames", "n": 1},
              {"do": "report", "path": tmp_path / "lamp.json", "settle": False}, {"do": "quit"}]
    (tmp_path / "script.json").write_text(json.dumps(script, default=str))
    res = run_viewer([CARDS_PLY, "--width", 320, "--height", 240, "--focus", 4, "--script", tmp_path / "script.json"],
                     {**os.environ, "DISPLAY": display})
    assert res.returncode == 0, res.stderr
    cards, lamp = (json.loads((tmp_path / f"{n}.json").read_text()) for n in ("cards", "lamp"))
    assert cards["colour_space"] == "srgb" and cards["tonemap"]["operator"] == "clip"
    assert lamp["colour_space"] == "linear" and lamp["tonemap"]["operator"] == LINEAR_DEFAULT


def test_statistics_as_numpy_numbers_reach_the_display_pass():
    """The viewer's smoothed statistics are numpy numbers, and reinhard05's test of them, "the
    frame fits under white", a numpy bool, which moderngl cannot pack into a bool uniform: the
    viewer stopped with a traceback on the lamp sample at +3 EV (found by random viewer scripts).
    The display pass takes them, and shows what it shows with the same statistics as floats."""
    from dataclasses import fields, replace

    from dofview.camera import look_at
    from dofview.io import load_scene
    from dofview.lens import Lens
    from dofview.rendering.quad import QuadBackend
    from dofview.tonemap import Tonemap
    from dofview.tonemap.reinhard05 import Reinhard05

    scene = load_scene(LAMP_PLY, progress=False)
    renderer = QuadBackend(scene)
    try:
        renderer.render(look_at([0, 0, -4], [0, 0, 0], 64, 48, 60), Lens(4.0, 0.0))
        operator = Reinhard05()
        stats = renderer.frame_stats(operator)
        numpy_stats = replace(stats, **{f.name: np.float64(getattr(stats, f.name)) for f in fields(stats)
                                        if isinstance(getattr(stats, f.name), float)})
        tm = Tonemap(exposure=3.0, operator=operator)
        assert isinstance(operator.uniforms(numpy_stats, tm.multiplier)["u_identity"], np.bool_)
        shown = renderer.display_image(tm, stats=numpy_stats)
        assert np.array_equal(shown, renderer.display_image(tm, stats=stats)) and shown.any()
    finally:
        renderer.release()
