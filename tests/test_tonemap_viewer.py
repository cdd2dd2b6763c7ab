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
MAX_STEP_CHANGE = 0.02  # mean display luminance (linear, of [0, 1]) between consecutive captured frames
MIN_ADAPTATION_STOPS = 0.2


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
    means = np.array([_mean_luminance(swing / f"step{i:02d}.png") for i in range(STEPS)])
    assert np.abs(np.diff(means)).max() <= MAX_STEP_CHANGE, np.diff(means)
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
    from dofview.rendering.quads import QuadBackend
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
