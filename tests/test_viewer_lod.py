"""The viewer streaming a LOD set (viewer/streaming.py, ViewerViews.swap_chunks), headless on EGL:
the leaves' levels follow the camera (finer near, coarser far, within --budget), the chunks are
decoded, gathered, packed and sorted off the UI thread, and the settled frame is what a renderer of
the chosen Gaussians draws."""

from __future__ import annotations

import json
import os
import threading
import time

import numpy as np
import pytest
from lod_sets import ROOT, cards_set, sh_set
from test_viewer import display, run_viewer  # noqa: F401  (display is a fixture)
from test_viewer_model import SIZE, settle

from dofview.io import load_scene
from dofview.io.cameras import load_cameras_json
from dofview.io.lod import LodSet, open_lod
from dofview.rendering import get_backend
from dofview.rendering.gl import headless_context
from dofview.viewer.model import ViewerModel
from dofview.viewer.settings import ViewerSettings


def open_lod_model(budget: int, raster: str = "quad", lod: int | None = None) -> ViewerModel:
    path = cards_set()
    lod_set = open_lod(path)
    scene = load_scene(path, progress=False, budget=budget, lod=lod, lod_set=lod_set)
    cameras = load_cameras_json(ROOT / "samples" / "cards_cameras.json")
    s = ViewerSettings(colour_space=scene.colour_space, smooth_focus=False, lens_samples_max=0)
    model = ViewerModel(headless_context(), lambda: SIZE, scene, path, s, None, cameras, raster=raster,
                        lod_set=lod_set, budget=budget, lod=lod)
    model.frame_lens()
    return model


def settle_stream(model: ViewerModel, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    settle(model, timeout_s)
    while model.stream.pending or not model.settled:
        assert time.monotonic() < deadline, "the stream did not settle"
        time.sleep(0.01)
        model.update(time.perf_counter())


@pytest.mark.parametrize("raster", ["quad", "compute"])
def test_leaves_follow_the_camera_within_the_budget(raster, monkeypatch):
    """Read at the coarse level (the finest within 16,000 Gaussians), the set opens with the leaves
    near the first view refined; moving the camera round to the other side changes the choice. The
    subsets the frames take are gathered off the UI thread, and each settled frame is what a fresh
    renderer of its Gaussians draws."""
    budget = 16_000
    model = open_lod_model(budget, raster)
    lod_set: LodSet = model.lod_set
    threads = []
    gather = LodSet.gather
    monkeypatch.setattr(LodSet, "gather", lambda self, *a: threads.append(threading.current_thread()) or gather(self, *a))
    try:
        seen = []
        for _ in range(2):
            settle_stream(model)
            choice = lod_set.select(model.camera().centre, budget)
            assert np.array_equal(model.stream.choice, choice) and 0 in choice and 1 in choice
            assert model.scene.count == lod_set.selection_count(choice) <= budget
            assert model.renderer.scene is model.scene and model.report()["lod"]["levels"] == choice.tolist()
            fresh = get_backend(raster, model.scene)
            cam = model.camera()
            want = fresh.render(cam, model.lens(cam), model.settings.render)
            fresh.release()
            assert np.array_equal(model.renderer.read().rgba, want.rgba)
            seen.append(choice)
            model.controls.orbit(600.0, 0.0)  # round to the other side of the cards
        assert not np.array_equal(*seen) and model.stream.swaps >= 1
        assert threads and threading.main_thread() not in threads
    finally:
        model.close()


def test_lod_keeps_the_level_and_the_command_line_says_it():
    model = open_lod_model(16_000, lod=0)
    try:
        assert model.stream is None and model.scene.count == 19129
        settle(model)
        model.controls.orbit(300.0, 0.0)
        settle(model)
        assert model.scene.count == 19129 and "--lod 0" in model.command_line()
    finally:
        model.close()


def test_a_chunk_that_cannot_be_decoded_stops_nothing(tmp_path):
    """A chunk spoilt after the set was opened: the stream reports it in one line and the scene drawn
    stays (the viewer goes on)."""
    import shutil

    shutil.copytree(cards_set().parent, tmp_path / "set")
    path = tmp_path / "set" / "lod-meta.json"
    lod_set = open_lod(path)
    scene = load_scene(path, progress=False, budget=16_000, lod_set=lod_set)
    for c in lod_set.chunks:
        if c is not None and c.level == 0:
            (c.path.parent / "sh0.webp").write_bytes(b"RIFF")
    cameras = load_cameras_json(ROOT / "samples" / "cards_cameras.json")
    s = ViewerSettings(colour_space="srgb", smooth_focus=False, lens_samples_max=0)
    model = ViewerModel(headless_context(), lambda: SIZE, scene, path, s, None, cameras, lod_set=lod_set, budget=16_000)
    try:
        model.frame_lens()
        settle_stream(model)
        assert "sh0.webp is not a readable WebP image" in model.stream.error and str(path) in model.stream.error
        assert model.scene.count == 9565 and model.report()["lod"]["error"] == model.stream.error
    finally:
        model.close()


def test_the_window_streams_a_set_and_opens_another(display, tmp_path):  # noqa: F811
    """``dofview view SET --budget 16k`` under Xvfb: the first view's leaves mixed within the budget,
    chunks swapped as the camera orbits; a set's folder dropped on the window opens and streams."""
    script = [{"do": "report", "path": tmp_path / "open.json"}, {"do": "orbit", "dx": 600, "dy": 0},
              {"do": "settle"}, {"do": "report", "path": tmp_path / "moved.json"},
              {"do": "open", "path": sh_set().parent}, {"do": "report", "path": tmp_path / "other.json"},
              {"do": "quit"}]
    (tmp_path / "script.json").write_text(json.dumps(script, default=str))
    res = run_viewer([cards_set().parent, "--budget", "16k", "--cameras", ROOT / "samples" / "cards_cameras.json",
                      "--width", "420", "--height", "240", "--script", tmp_path / "script.json"],
                     {**os.environ, "DISPLAY": display})
    assert res.returncode == 0, res.stderr
    assert "level 1 (the finest within the budget of 16,000)" in res.stderr
    r = {n: json.loads((tmp_path / f"{n}.json").read_text()) for n in ("open", "moved", "other")}
    for n in ("open", "moved"):
        levels = r[n]["lod"]["levels"]
        assert 0 in levels and 1 in levels and r[n]["count"] <= 16_000 and r[n]["error"] == ""
    assert r["moved"]["lod"]["levels"] != r["open"]["lod"]["levels"] and r["moved"]["lod"]["swaps"] >= 1
    assert r["other"]["count"] == 3200 and r["other"]["lod"]["levels"] == [0] * 4 and r["other"]["error"] == ""


@pytest.mark.parametrize("raster, seed", [("quad", 1), ("compute", 2)])
def test_a_random_walk_keeps_the_stream_and_the_frames_sound(raster, seed, tmp_path):
    """40 frames of random actions as mouse, keys and panel make them (orbit, pan, zoom, look,
    focus, aperture, blades, blur method, τ, click-to-focus, save, rest), the stream swapping
    leaves as the camera goes: every frame finite and within the budget, no error from the model or
    its stream; settled at the end, the frame is what a fresh renderer of its Gaussians draws."""
    import math
    import random
    from dataclasses import replace

    budget = 16_000
    model = open_lod_model(budget, raster)
    rnd = random.Random(seed)
    try:
        for step in range(40):
            action = rnd.choice(["orbit", "orbit", "pan", "zoom", "look", "focus", "aperture", "blades", "dof",
                                 "tau", "click", "save", "rest"])
            if action == "orbit":
                model.controls.orbit(rnd.uniform(-300, 300), rnd.uniform(-40, 40))
            elif action == "pan":
                model.controls.pan(rnd.uniform(-40, 40), rnd.uniform(-40, 40), model.camera().fx)
            elif action == "zoom":
                model.controls.zoom(rnd.choice([-3, -1, 1, 3]))
            elif action == "look":
                model.controls.look(rnd.uniform(-50, 50), rnd.uniform(-20, 20))
            elif action == "focus":
                model.set_focus(math.exp(rnd.uniform(math.log(0.5), math.log(50.0))))
            elif action == "aperture":
                model.settings.aperture = rnd.choice([0.0, 5.0, 50.0, 300.0])
            elif action == "blades":
                model.settings.render = replace(model.settings.render, blades=rnd.choice([0, 5, 6]))
            elif action == "dof":
                model.settings.render = replace(model.settings.render, dof=rnd.choice(["sliced", "splat"]))
            elif action == "tau":
                model.with_render(tau=rnd.choice([0.0, 1 / 255, 0.02]))
            elif action == "click":
                model.focus_at(rnd.uniform(0, SIZE[0] - 1), rnd.uniform(0, SIZE[1] - 1))
            elif action == "save":
                model.save(tmp_path / f"step{step}.exr", png=rnd.random() < 0.5)
                assert (tmp_path / f"step{step}.exr").is_file()
            else:
                time.sleep(0.15)  # the view rests: the full frame follows the previews
            model.update(time.perf_counter())
            frame = model.renderer.read()
            assert np.isfinite(frame.rgba).all() and np.isfinite(frame.depth).all(), (step, action)
            assert model.scene.count <= budget and not model.error and model.stream.error is None, (step, action)
        settle_stream(model)
        assert model.stream.swaps >= 1
        fresh = get_backend(raster, model.scene)
        cam = model.camera()
        want = fresh.render(cam, model.lens(cam), model.settings.render)
        fresh.release()
        assert np.array_equal(model.renderer.read().rgba, want.rgba)
    finally:
        model.close()
