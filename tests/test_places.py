"""The views from inside the shared places (dofview/bench/places): files in cameras.json form with a
focus, found from a scene's path. The places themselves are not in the repository (no licence), so
the tests read only the view files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dofview.bench import places
from dofview.bench.places import PlaceView, place_names, place_of, place_views
from dofview.errors import DofviewError
from dofview.io.cameras import load_cameras_json


def test_each_place_has_a_near_and_a_far_view():
    assert place_names() == ["corridor", "kitchen_balcony", "showroom"]
    for place in place_names():
        views = place_views(place)
        assert [v.camera.name for v in views] == [f"{place}_1", f"{place}_2"]
        near, far = (v.focus for v in views)
        assert 0 < near < far  # _1 focuses near, _2 far
        for camera, focus in views:
            assert 240 <= camera.width <= 480 and camera.height > 0  # small enough for llvmpipe
            assert np.allclose(camera.R @ camera.R.T, np.eye(3), atol=1e-5) and np.linalg.det(camera.R) > 0
            assert np.isfinite(focus)


def test_the_files_are_cameras_files_with_a_focus_and_a_subject():
    """`dofview render SCENE --cameras FILE` reads them as they are (the extra keys are ignored)."""
    files = sorted(places.VIEWS.glob("*.json"))
    assert len(files) >= 6
    for path in files:
        (camera,) = load_cameras_json(path)
        (entry,) = json.loads(path.read_text())
        assert camera.name == path.stem and entry["focus"] > 0 and entry["subject"]


@pytest.mark.parametrize("scene, place", [
    ("/data/scenes/corridor.compressed.ply", "corridor"),
    ("/data/kitchen_balcony.compressed.ply", "kitchen_balcony"),
    ("/data/scenes/showroom/lod-meta.json", "showroom"),
    ("/tmp/showroom_l1.ply", "showroom"),  # a level decoded by splat-transform
    ("showroom", "showroom"),
    ("tests/data/burger.ply", None),
    ("corridors.ply", None),
])
def test_a_scene_path_names_its_place(scene, place):
    assert place_of(scene) == place
    assert (place_views(scene) == []) == (place is None)


def test_a_view_without_a_focus_is_refused(tmp_path, monkeypatch):
    entry = {"id": 0, "img_name": "hall_1", "width": 320, "height": 240, "position": [0, 0, 0],
             "rotation": np.eye(3).tolist(), "fx": 230.0, "fy": 230.0}
    (tmp_path / "hall_1.json").write_text(json.dumps([entry]))
    monkeypatch.setattr(places, "VIEWS", tmp_path)
    with pytest.raises(DofviewError, match="hall_1.json.*focus"):
        place_views("hall")
    (tmp_path / "hall_1.json").write_text(json.dumps([{**entry, "focus": 2.5}]))
    (view,) = place_views("/x/hall.ply")
    assert isinstance(view, PlaceView) and view.camera.name == "hall_1" and view.focus == 2.5
