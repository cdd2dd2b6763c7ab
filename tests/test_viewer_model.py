"""The viewer's model without a window: built headless on EGL, it opens a scene at a training view,
focuses automatically, takes an aperture, sorts in the background while the view moves, refines the
thin lens while it rests and saves what `dofview render` would write."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from dofview.frame import RenderSettings
from dofview.io import load_scene
from dofview.io.cameras import load_cameras_json
from dofview.io.exr import read_exr
from dofview.lens import Lens
from dofview.rendering import get_backend
from dofview.rendering.focus import auto_focus
from dofview.rendering.gl import headless_context
from dofview.rendering.progressive import render_lens_samples
from dofview.viewer.model import ViewerModel
from dofview.viewer.settings import START_COC_PX, ViewerSettings

ROOT = Path(__file__).resolve().parent.parent
CARDS = ROOT / "samples" / "cards.ply"
SIZE = (96, 72)


def open_model(raster: str = "quad", **settings) -> ViewerModel:
    scene = load_scene(CARDS, progress=False)
    cameras = load_cameras_json(ROOT / "samples" / "cards_cameras.json")
    s = ViewerSettings(colour_space=scene.colour_space, smooth_focus=False, **settings)
    model = ViewerModel(headless_context(), lambda: SIZE, scene, CARDS, s, None, cameras, raster=raster)
    model.frame_lens()
    return model


def settle(model: ViewerModel, timeout_s: float = 30.0) -> None:
    """Run frames until the model is settled (a background sort has come in and been drawn)."""
    deadline = time.monotonic() + timeout_s
    model.update(time.perf_counter())
    while not model.settled:
        assert time.monotonic() < deadline, "the model did not settle"
        time.sleep(0.005)
        model.update(time.perf_counter())


@pytest.mark.parametrize("raster", ["quad", "compute"])
def test_open_focus_aperture_save(tmp_path, raster):
    model = open_model(raster, lens_samples_max=0)
    try:
        cam = model.camera()
        assert (cam.width, cam.height) == SIZE and model.view_index == 0
        # opened sharp: focused at what is under the centre, aperture for START_COC_PX of blur
        expected_focus = auto_focus(get_backend(raster, model.scene).render(cam, Lens(1.0, 0.0), RenderSettings()))
        assert model.settings.focus == pytest.approx(expected_focus)
        assert model.settings.aperture == pytest.approx(model.aperture_for_blur(START_COC_PX))
        model.settings.aperture = 40.0
        settle(model)
        assert model.renderer.stats.drawn > 0 and model.splat_draws >= 1
        out = tmp_path / "view.exr"
        model.save(out, png=False)
        assert model.error == "" and model.message == f"saved {out}"
        channels, _ = read_exr(out)
        headless = get_backend(raster, model.scene).render(cam, Lens(model.settings.focus, 40.0), model.settings.render)
        assert np.array_equal(channels["R"], headless.rgba[..., 0]) and np.array_equal(channels["Z"], headless.depth)
        assert "--aperture" in model.command_line() and str(CARDS) in model.command_line()
    finally:
        model.close()


def test_save_makes_a_new_folder_and_refuses_a_path_under_a_file(tmp_path):
    model = open_model("quad", lens_samples_max=0)
    try:
        settle(model)
        (tmp_path / "afile").write_text("")
        model.save(tmp_path / "afile" / "view.exr", png=True)
        assert "afile is a file, not a folder" in model.error and not model.message
        model.save(tmp_path / "shots" / "a" / "view.exr", png=True)
        assert model.error == "" and model.message.startswith("saved")
        assert sorted(p.name for p in (tmp_path / "shots" / "a").iterdir()) == ["view.exr", "view.png"]
    finally:
        model.close()


def test_moving_view_sorts_in_the_background_then_draws_the_current_order():
    model = open_model("quad", lens_samples_max=0)
    try:
        settle(model)
        before = model.renderer.stats.sort_requests
        model.controls.orbit(40.0, 0.0)
        model.update(time.perf_counter())  # drawn at once with the last order while the new one is sorted
        assert model.renderer.stats.sort_requests == before + 1
        settle(model)
        shown = model.renderer.read().rgba
        fresh = get_backend("quad", model.scene).render(model.camera(), model.lens(), model.settings.render).rgba
        assert np.array_equal(shown, fresh)  # the settled frame uses the order sorted for this view
        model.settings.aperture *= 2  # a lens change does not sort again
        settle(model)
        assert model.renderer.stats.sort_requests == before + 1
    finally:
        model.close()


def test_still_view_refines_the_thin_lens_in_complete_stages():
    """Still frames refine in stages N = 1, 2, 4, 8: every frame shows the last complete stage, bit
    for bit what ``dofview render --lens-samples N`` renders, from the second still frame N = 2 (its
    two passes drawn in one frame, the later stages' one a frame)."""
    model = open_model("quad", lens_samples_max=8)
    try:
        model.settings.aperture = 60.0
        settle(model)  # the single pass: stage 1
        fresh = get_backend("quad", model.scene)
        expected = {n: render_lens_samples(fresh, model.camera(), model.lens(), model.settings.render, n)
                    for n in (1, 2, 4, 8)}
        fresh.release()
        shown = [model.progressive.samples]
        frames = [model.renderer.read()]
        assert model.last_pass[0] == "depth layers" and model.last_pass[1] > 0  # the single pass
        passes = [model.passes]
        while model.progressive.samples < 8:
            model.update(time.perf_counter())
            shown.append(model.progressive.samples)
            frames.append(model.renderer.read())
            passes.append(model.passes)
            # each still frame drew a refinement pass, which the status names and times
            assert model.last_pass[0] == "thin-lens refinement" and model.last_pass[1] > 0
        assert shown == [1, 2] + [2] * 3 + [4] + [4] * 7 + [8]  # 2 + 4 + 8 passes after the single one
        assert np.array_equal(np.diff(passes), np.ones(len(passes) - 1))
        for n, frame in zip(shown, frames):
            assert np.array_equal(frame.rgba, expected[n].rgba) and np.array_equal(frame.depth, expected[n].depth)
        assert not model.renderer.targets_encoded and not frames[-1].encoded  # stages average linear light
        assert model.renderer.lens == model.lens()  # the focus aid reads the shown lens, not a pass's
        model.update(time.perf_counter())
        assert model.progressive.samples == 8  # lens_samples_max reached: no more passes
        assert model.passes == passes[-1]  # the image kept: no pass drawn
    finally:
        model.close()


def test_model_imports_no_window_toolkit():
    """The model needs neither glfw nor ImGui (only the window and its panel do)."""
    import subprocess
    import sys

    code = "import sys, dofview.viewer.model; print(sorted(m for m in ('glfw', 'imgui_bundle') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
