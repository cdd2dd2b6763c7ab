"""Progressive thin lens (rendering/progressive.py): stages of sub-aperture passes. Stage 1 is the
single pass bit for bit, a stage is accumulate.py's average of its passes, every stage is closer to
the thin lens than the single pass and fills a point's circle where the pinhole average showed copies; in the
viewer (Xvfb) the still frames reach what ``dofview render --lens-samples N`` writes, and a camera move
restarts it."""

from __future__ import annotations

import json
import math
import os
import shlex
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
from conftest import psnr, random_scene
from test_viewer import CARDS_PLY, ROOT, display, run_viewer  # noqa: F401  (display is a fixture)

from dofview.bench.refinement import disk_sequence
from dofview.bench.sliced_study import cases_for
from dofview.bench.variants import errors, make_references
from dofview.camera import look_at
from dofview.frame import RenderSettings
from dofview.io import load_scene
from dofview.io.cameras import load_cameras_json
from dofview.io.png import read_png
from dofview.lens import Lens
from dofview.rendering.accumulate import accumulate
from dofview.rendering.progressive import (
    lens_cells,
    pass_settings,
    render_lens_samples,
    stage_points,
    sub_lens,
)
from dofview.rendering.quad import QuadBackend
from dofview.scene import GaussianScene
from dofview.tonemap import Tonemap
from dofview.viewer.panel import PANEL_WIDTH

CAM = look_at([0.2, -0.1, 0.0], [0.0, 0.0, 5.0], 96, 72, 60)
MARGIN_DB = {"sliced": 0.3, "splat": 1.0}
"""Measured on cards at 96×72, 6 px of blur, over the single pass of the mode: sliced +0.69 dB at
N = 2 rising to +3.6 at N = 8 (and +5.7 at 16); per-splat +1.6 at N = 2, +6.4 at N = 8."""


@pytest.mark.parametrize("layout", ["cvt", "sunflower"])
@pytest.mark.parametrize("n", [1, 2, 3, 4, 8, 16, 64, 65])
def test_stage_points_are_centred_and_have_the_lens_second_moment(n, layout):
    p = stage_points(n, layout=layout)
    assert p.shape == (n, 2)
    np.testing.assert_allclose(p.mean(axis=0), 0.0, atol=1e-12)  # no shift of out-of-focus content
    # the points' second moment plus a sub-aperture disk's (radius 1/√n: r²/2) is the unit disk's (1/2)
    assert math.isclose(np.mean(np.sum(p * p, axis=1)) + 0.5 / n, 0.5, rel_tol=1e-12)
    assert np.all(np.hypot(*p.T) <= 1.0)


def test_one_stage_pass_is_the_single_pass_exactly():
    r = QuadBackend(random_scene(seed=5, colour_space="srgb"))
    lens, settings = Lens(focus=4.0, aperture=150.0), RenderSettings()
    single = r.render(CAM, lens, settings)
    got = render_lens_samples(r, CAM, lens, settings, 1)
    assert np.array_equal(got.rgba, single.rgba) and np.array_equal(got.depth, single.depth)
    assert got.encoded == single.encoded
    r.release()


def test_a_stage_is_the_average_of_its_sub_aperture_passes():
    """Per-splat: pass i from stage_points(n)[i] through the sub-aperture A/√n, averaged."""
    scene = random_scene(seed=5, colour_space="srgb")
    lens, settings, n = Lens(focus=4.0, aperture=150.0), RenderSettings(dof="splat"), 6
    r = QuadBackend(scene)
    got = render_lens_samples(r, CAM, lens, settings, n)
    want = accumulate(lambda c: r.render(c, sub_lens(lens, n), settings), CAM, lens, n, points=stage_points(n))
    assert sub_lens(lens, n).aperture == pytest.approx(150.0 / math.sqrt(n))
    assert psnr(got.rgba, want.rgba) >= 90.0  # the same sums, on the GPU instead of numpy
    np.testing.assert_allclose(got.depth, want.depth, rtol=1e-5, atol=1e-5)
    r.release()


def test_a_sliced_stage_is_the_share_weighted_sum_of_its_lens_cells():
    """Sliced (the default): pass i from lens cell i's centroid, blurred by the cell's own kernel at
    the whole lens's CoC, weighed by the cell's share, summed in linear light."""
    scene = random_scene(seed=5, colour_space="srgb")
    lens, settings, n = Lens(focus=4.0, aperture=150.0), RenderSettings(), 6
    r = QuadBackend(scene)
    got = render_lens_samples(r, CAM, lens, settings, n)
    cells = lens_cells(n)
    radius = 0.5 * lens.diameter(CAM.fx)
    rgba = np.zeros((CAM.height, CAM.width, 4))
    for cell in cells:
        u, v = cell.point * radius
        r.draw(CAM.lens_shifted(float(u), float(v), lens.focus), lens, settings, cell=cell)
        rgba += cell.share * r.read().rgba
    r.release()
    assert len(cells) == n and sum(c.share for c in cells) == pytest.approx(1.0)
    assert psnr(got.rgba, rgba.astype(np.float32)) >= 90.0


@pytest.mark.parametrize("dof", ["sliced", "splat"])
def test_every_stage_is_closer_to_the_thin_lens_than_the_single_pass(dof):
    scene = load_scene(CARDS_PLY, progress=False)
    cam = load_cameras_json(CARDS_PLY.with_name("cards_cameras.json"))[0].resized(96, 72)
    r = QuadBackend(scene)
    lens, settings = cases_for(r, cam, blurs=(6.0,))[0], RenderSettings(dof=dof)
    truth = make_references(r, cam, lens, RenderSettings(), 64, False, lambda: None).physical
    single = errors(r.render(cam, lens, settings), truth, Tonemap(), False)["psnr"]
    for n in range(2, 17):  # the range: every stage from 2 to 16
        staged = errors(render_lens_samples(r, cam, lens, settings, n), truth, Tonemap(), False)["psnr"]
        assert staged >= single + MARGIN_DB[dof], (n, staged, single)
    r.release()


def _blobs(img: np.ndarray) -> int:
    """Connected regions (4-neighbours) of ``img`` (H, W) at or above half its maximum: copies."""
    on = img >= 0.5 * img.max()
    seen = np.zeros_like(on)
    count = 0
    for start in zip(*np.nonzero(on)):
        if seen[start]:
            continue
        count += 1
        stack = [start]
        seen[start] = True
        while stack:
            y, x = stack.pop()
            for q in ((y + 1, x), (y - 1, x), (y, x + 1), (y, x - 1)):
                if 0 <= q[0] < on.shape[0] and 0 <= q[1] < on.shape[1] and on[q] and not seen[q]:
                    seen[q] = True
                    stack.append(q)
    return count


def test_a_far_out_of_focus_point_fills_its_circle_instead_of_copies():
    """One small bright splat at z = 2 seen with focus 6: a CoC of radius 12 px. Four pinhole passes
    show four separate copies of it, lighting a few pixels of the circle, off its centre. Four lens
    cells (the default, sliced) tile the circle: all of its core lit, evenly (measured: 100 %, a
    spread of 15 % about the mean), centred, and the point's light kept. Four per-splat
    sub-aperture passes light most of it, as four overlapping lumps (the Gaussian kernel at k = 1/4
    is narrower than a quarter of the lens; measured 94 %), and lose light at the τ cut."""
    dot = GaussianScene(means=np.array([[0.0, 0.0, 2.0]]), quats=np.array([[1.0, 0.0, 0.0, 0.0]]),
                        scales=np.full((1, 3), 0.004), opacities=np.array([0.95]), sh_dc=np.full((1, 3), 1.7),
                        colour_space="srgb")
    cam = look_at([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 64, 64, 60)
    lens = Lens(focus=6.0, aperture=12.0 / (0.5 * (1 / 2.0 - 1 / 6.0)))
    r = QuadBackend(dot)
    cells = render_lens_samples(r, cam, lens, RenderSettings(), 4).rgba[..., 3]
    lumps = render_lens_samples(r, cam, lens, RenderSettings(dof="splat"), 4).rgba[..., 3]
    pin = r.render(cam, Lens(lens.focus, 0.0), pass_settings(RenderSettings())).rgba[..., 3]
    pinholes = accumulate(lambda c: r.render(c, Lens(lens.focus, 0.0), pass_settings(RenderSettings())), cam, lens,
                          4, points=disk_sequence(4)).rgba[..., 3]
    r.release()
    yy, xx = np.mgrid[:64, :64] + 0.5
    core = np.hypot(yy - 32.0, xx - 32.0) <= 0.75 * 12.0

    def lit(img):  # the share of the circle's core lit at ≥ 1/5 of the image's peak
        return float(np.mean(img[core] >= 0.2 * img.max()))

    def centroid(img):
        return np.array([(img * yy).sum(), (img * xx).sum()]) / img.sum()

    assert _blobs(pinholes) == 4 and lit(pinholes) < 0.1  # measured: four copies, 4 % of the core
    assert np.abs(centroid(pinholes) - 32.0).max() > 1.0  # four copies' mean lies off it
    assert lit(cells) == 1.0 and cells[core].std() < 0.25 * cells[core].mean()
    assert cells.sum() == pytest.approx(pin.sum(), rel=0.01)
    assert lit(lumps) >= 0.9
    for img in (cells, lumps):
        np.testing.assert_allclose(centroid(img), [32.0, 32.0], atol=0.1)  # the point's image, no shift


def test_viewer_refines_to_render_lens_samples_and_restarts_on_a_move(display, tmp_path):  # noqa: F811
    n = 8  # stages 1, 2, 4, 8
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


@pytest.mark.parametrize("dof", ["sliced", "splat"])
def test_lens_shifted_passes_keep_the_depth_order_and_sort_once(dof, monkeypatch):
    """Camera z depends on R[2] and T[2] only, so every lens-shifted pass of a stage has the order
    of the unshifted view: the quad backend sorts once for a whole stage (issue 28: once a pass)."""
    from dofview.rendering import quad
    from dofview.rendering.depth_order import front_to_back

    scene = random_scene(seed=5, colour_space="srgb")
    lens = Lens(focus=4.0, aperture=150.0)
    shifted = CAM.lens_shifted(0.05, -0.03, lens.focus)
    assert np.array_equal(front_to_back(scene.means, shifted), front_to_back(scene.means, CAM))
    sorts = []
    monkeypatch.setattr(quad, "front_to_back", lambda *a: sorts.append(a) or front_to_back(*a))
    r = QuadBackend(scene)
    try:
        render_lens_samples(r, CAM, lens, RenderSettings(dof=dof), 4)
        assert len(sorts) == 1
        r.draw(CAM, lens, RenderSettings(dof=dof))  # the unshifted view: the same order
        assert len(sorts) == 1
        r.draw(replace(CAM, T=CAM.T + np.array([0.0, 0.0, 0.1])), lens, RenderSettings(dof=dof))  # a dolly: sorted
        assert len(sorts) == 2
    finally:
        r.release()
