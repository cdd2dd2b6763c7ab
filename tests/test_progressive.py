"""Progressive thin lens (rendering/progressive.py): headless it is accumulate.py with the same lens
points; in the viewer (Xvfb) N still frames show what ``dofview render --lens-samples N`` writes, and
a camera move restarts it."""

from __future__ import annotations

import json
import os
import shlex
import subprocess
import sys

import numpy as np
from conftest import psnr, random_scene
from test_viewer import CARDS_PLY, ROOT, display, run_viewer  # noqa: F401  (display is a fixture)

from dofview.camera import look_at
from dofview.frame import RenderSettings
from dofview.io.png import read_png
from dofview.lens import Lens
from dofview.rendering.accumulate import accumulate
from dofview.rendering.progressive import (
    SHOW_AFTER,
    disk_sequence,
    pass_settings,
    render_lens_samples,
)
from dofview.rendering.quads import QuadBackend
from dofview.viewer.panel import PANEL_WIDTH

CAM = look_at([0.2, -0.1, 0.0], [0.0, 0.0, 5.0], 96, 72, 60)


def test_disk_sequence_is_one_sequence_inside_the_disk():
    a, b = disk_sequence(16), disk_sequence(64)
    np.testing.assert_array_equal(a, b[:16])  # N samples are the first N of any longer run
    assert np.all(np.hypot(*b.T) <= 1.0)
    assert np.abs(b.mean(axis=0)).max() < 0.05  # spread evenly: the centroid sits near the centre


def test_lens_samples_equal_the_accumulation_with_the_same_points():
    scene = random_scene(seed=5, colour_space="srgb")
    lens, settings = Lens(focus=4.0, aperture=150.0), RenderSettings()
    r = QuadBackend(scene)
    got = render_lens_samples(r, CAM, lens, settings, 12)
    want = accumulate(lambda c: r.render(c, Lens(lens.focus, 0.0), pass_settings(settings)), CAM, lens, 12,
                      points=disk_sequence(12))
    assert psnr(got.rgba, want.rgba) >= 90.0  # the same sums, on the GPU instead of numpy
    np.testing.assert_allclose(got.depth, want.depth, rtol=1e-5, atol=1e-5)
    r.release()


def test_viewer_refines_to_render_lens_samples_and_restarts_on_a_move(display, tmp_path):  # noqa: F811
    n = SHOW_AFTER + 4
    script = [
        {"do": "set", "focus": 4.0, "aperture": 30.0, "lens_samples_max": n},
        {"do": "still", "samples": n},
        {"do": "capture", "path": tmp_path / "still.png"},
        {"do": "report", "path": tmp_path / "still.json"},
        {"do": "orbit", "dx": 20.0, "dy": 0.0},
        {"do": "frames", "n": 1},
        {"do": "report", "path": tmp_path / "moved.json", "settle": False},
        {"do": "quit"},
    ]
    (tmp_path / "script.json").write_text(json.dumps(script, default=str))
    env = {**os.environ, "DISPLAY": display}
    res = run_viewer([CARDS_PLY, "--width", PANEL_WIDTH + 160, "--height", 120, "--focus", "4",
                      "--script", tmp_path / "script.json"], env)
    assert res.returncode == 0, res.stderr
    still = json.loads((tmp_path / "still.json").read_text())
    moved = json.loads((tmp_path / "moved.json").read_text())
    assert still["lens_samples"] == n
    assert moved["lens_samples"] <= 1  # the move restarted the accumulation

    cmd = shlex.split(still["command"]) + ["--lens-samples", str(n), "--png", str(tmp_path / "cli.png")]
    cmd[cmd.index("-o") + 1] = str(tmp_path / "cli.exr")
    res = subprocess.run([sys.executable, "-m", "dofview", *cmd[1:]], cwd=ROOT, capture_output=True, text=True,
                         timeout=240, check=False)
    assert res.returncode == 0, res.stderr
    shown, cli = read_png(tmp_path / "still.png"), read_png(tmp_path / "cli.png")
    assert shown.shape == cli.shape
    assert psnr(shown, cli, 255.0) >= 45.0
