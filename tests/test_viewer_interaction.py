"""The viewer's interaction budget (viewer/interaction.py): while the view moves, the best preview
whose measured cost is within the pinhole frame × 1.2; once it rests, the full frame and then the
refinement. The rule is tested with the costs it is told; the model headless on EGL, with times
given (no wall-clock assertion)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from test_viewer_model import open_model, settle

from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering import get_backend
from dofview.viewer.interaction import LADDERS, STILL_AFTER_S, InteractionBudget, Preview

FULL, SPLAT, HALF = Preview("sliced"), Preview("splat"), Preview("sliced", 2)


def test_still_or_unmeasured_draws_the_full_frame():
    b = InteractionBudget()
    assert b.choose("sliced", moving=True) == FULL  # no pinhole frame timed yet: no budget
    b.record_pinhole(10.0, now=0.0)
    assert b.budget_ms == pytest.approx(12.0)
    assert b.choose("sliced", moving=False) == FULL


def test_moving_takes_the_best_rung_within_the_budget():
    b = InteractionBudget()
    b.record_pinhole(10.0, now=0.0)
    assert b.choose("sliced", True) == FULL  # never measured: tried
    b.record(FULL, 30.0)
    assert b.choose("sliced", True) == SPLAT  # the next rung, never measured: tried
    b.record(SPLAT, 13.0)
    assert b.choose("sliced", True) == HALF
    b.record(HALF, 8.0)
    assert b.choose("sliced", True) == HALF
    b.record(FULL, 10.0)  # the full frame measured again (a still frame) within the budget: 20 ms smoothed
    assert b.costs[FULL] == pytest.approx(20.0) and b.choose("sliced", True) == HALF
    b.record(FULL, 2.0)
    assert b.choose("sliced", True) == FULL
    for p in LADDERS["sliced"]:
        b.record(p, 1000.0)
        b.record(p, 1000.0)
    assert b.choose("sliced", True) == LADDERS["sliced"][-1]  # nothing affordable: the cheapest
    assert b.choose("splat", True) == Preview("splat", 4)


def test_moving_follows_state_changes_in_time():
    b = InteractionBudget()
    assert b.moving("a", 1.0)
    assert b.moving("a", 1.0 + STILL_AFTER_S / 2)
    assert not b.moving("a", 1.0 + 1.01 * STILL_AFTER_S)
    assert b.moving("b", 5.0)
    b.record_pinhole(10.0, now=5.0)
    assert not b.pinhole_due(6.0) and b.pinhole_due(20.0)
    b.pinhole_stale(0.5)  # half the Gaussians drawn: half the cost until timed again
    assert b.pinhole_due(6.0) and b.pinhole_ms == 5.0


def test_preview_view_keeps_the_blur_relative_to_the_image():
    model = open_model("quad", lens_samples_max=0)
    try:
        cam, lens = model.camera(), Lens(4.0, 80.0)
        small, small_lens, s = Preview("splat", 4).view(cam, lens, RenderSettings())
        assert (small.width, small.height) == (cam.width // 4, cam.height // 4) and s.dof == "splat"
        assert small_lens.aperture / small.fx == pytest.approx(lens.aperture / cam.fx)
        assert small.view_key() == cam.view_key()  # the same order
        assert FULL.view(cam, lens, RenderSettings()) == (cam, lens, RenderSettings())
    finally:
        model.close()


@pytest.mark.parametrize("raster", ["quad", "compute"])
def test_model_previews_while_moving_then_draws_the_full_frame(raster):
    """With the full frame measured over the budget, a lens change is drawn as the preview its costs
    afford; once the state rests the full frame follows, then the refinement, as before."""
    model = open_model(raster, lens_samples_max=2)
    try:
        settle(model)
        b = model.interaction
        b.forget()
        b.record_pinhole(10.0, now=time.perf_counter())
        b.costs.update({FULL: 100.0, SPLAT: 50.0})  # as if measured: half size is the best affordable
        t = time.perf_counter()
        model.settings.aperture = 60.0
        model.update(t)
        assert model.preview == HALF and model.previewing and model.busy and not model.settled
        cam = model.camera()
        fresh = get_backend(raster, model.scene)
        want = fresh.render(*HALF.view(cam, model.lens(cam), model.settings.render))
        got = model.renderer.read()
        assert got.rgba.shape[:2] == (cam.height // 2, cam.width // 2) and np.array_equal(got.rgba, want.rgba)
        assert model.progressive.samples == 0  # no refinement of a preview
        assert model.update(t + STILL_AFTER_S / 2)  # still changing: the preview stays
        model.update(t + 1.01 * STILL_AFTER_S)  # rested: the full frame
        assert model.preview == FULL and not model.previewing and model.progressive.samples == 1
        full = fresh.render(cam, model.lens(cam), model.settings.render)
        assert np.array_equal(model.renderer.read().rgba, full.rgba)
        model.update(t + 2 * STILL_AFTER_S)
        assert model.progressive.samples == 2  # the refinement follows the full frame
        fresh.release()
    finally:
        model.close()


def test_model_times_the_pinhole_again_once_the_view_rests():
    """A stale pinhole timing is not redone while the view moves (it would hold up the motion), but
    once the view rests with its image kept by the refinement; the image shown stays the same."""
    model = open_model("quad", lens_samples_max=4)
    try:
        model.settings.aperture = 40.0
        settle(model)
        b = model.interaction
        assert b.pinhole_ms is not None and not b.pinhole_due(time.perf_counter())  # timed as the view opened
        b.pinhole_stale(0.5)
        t = time.perf_counter()
        model.controls.orbit(20.0, 0.0)
        model.update(t)  # moving: drawn at once, nothing timed
        while model.renderer.sort_pending:  # the moved view's order, sorted in the background
            time.sleep(0.005)
            model.update(t)
        assert b.pinhole_due(t)
        model.update(t + 1.01 * STILL_AFTER_S)  # the full frame of the resting view
        shown = model.renderer.read().rgba
        assert model.progressive.samples == 1 and b.pinhole_due(t)
        assert not model.update(t + 2 * STILL_AFTER_S)  # the pinhole frame timed, the image put back
        assert not b.pinhole_due(time.perf_counter()) and np.array_equal(model.renderer.read().rgba, shown)
        model.update(t + 3 * STILL_AFTER_S)
        assert model.progressive.samples == 2  # then the refinement goes on
    finally:
        model.close()


def test_the_focus_drag_benchmark_drives_the_viewer_as_a_slider_does(tmp_path):
    """scripts/viewer_budget.py --drag focus (what scripts/gpu_bench.sh runs at 1M and 6M): the
    viewer's model, headless, with its focus moved every frame across the depths in view, reports
    each frame's time and host time, the previews the interaction budget chose (one a frame) and
    the still frame's layers; random:N scenes need no file."""
    root = Path(__file__).resolve().parents[1]
    out = tmp_path / "drag.json"
    env = {**os.environ, "PYTHONPATH": str(root)}
    done = subprocess.run([sys.executable, str(root / "scripts" / "viewer_budget.py"), "random:3000", "--drag", "focus",
                           "--width", "96", "--height", "54", "--steps", "6", "--json", str(out)],
                          capture_output=True, text=True, cwd=root, env=env, timeout=600)
    assert done.returncode == 0, done.stderr
    [row] = json.loads(out.read_text())
    assert row["drag"] == "focus" and row["start"] == row["end"] == 3000
    assert row["focus"][0] < row["focus"][1]  # the slider went somewhere
    assert sum(row["previews"].values()) == 6 and row["layers"] > 1
    assert min(row["median"], row["max"], row["host"], row["still"], row["pinhole"]) > 0

