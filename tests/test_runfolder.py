"""Run folders as the Inria trainer leaves them (built from tests/data's scenes): the folder or
the .ply inside it finds cameras.json, the highest iteration wins, --iteration picks one, and
`dofview render FOLDER` renders training view 0 at its own size."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import psnr
from inria_folder import BURGER, TWO_PLANES, make_run_folder, ring_cameras

from dofview.api import render
from dofview.camera import look_at
from dofview.cli import main
from dofview.errors import DofviewError
from dofview.framing import rig_centre, rig_up, robust_box
from dofview.io import load_scene
from dofview.io.cameras import load_cameras_json, save_cameras_json
from dofview.io.exr import read_exr
from dofview.io.runfolder import RunFolder, find_run
from dofview.lens import Lens


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A run with iterations 7000 (burger) and 30000 (two_planes) and six ring cameras on two_planes."""
    root = tmp_path_factory.mktemp("runs") / "two_planes"
    return make_run_folder(root, {7000: BURGER, 30000: TWO_PLANES}, ring_cameras(TWO_PLANES))


def test_folder_opens_the_highest_iteration_with_its_cameras(run):
    found = find_run(run)
    assert found.scene == run / "point_cloud" / "iteration_30000" / "point_cloud.ply"
    assert found.cameras == run / "cameras.json" and found.root == run and found.cfg_args == run / "cfg_args"
    assert (found.iteration, found.iterations) == (30000, (7000, 30000))
    assert found.describe(6) == f"run folder {run}: iteration 30000 (of 7000, 30000); {run / 'cameras.json'}: 6 views"


def test_iteration_picks_one_and_a_missing_one_is_an_error(run):
    assert find_run(run, 7000).scene == run / "point_cloud" / "iteration_7000" / "point_cloud.ply"
    with pytest.raises(DofviewError, match=r"no iteration 5 \(it has 7000, 30000\)"):
        find_run(run, 5)


def test_the_ply_inside_the_folder_finds_the_cameras_two_levels_up(run):
    ply = run / "point_cloud" / "iteration_7000" / "point_cloud.ply"
    found = find_run(ply)
    assert (found.scene, found.cameras, found.root, found.iteration) == (ply, run / "cameras.json", run, 7000)
    beside = find_run(TWO_PLANES)  # tests/data has no cameras.json anywhere near
    assert beside.cameras is None and beside.root is None
    with pytest.raises(DofviewError, match="give the folder, not a file"):
        find_run(ply, 7000)


def test_a_folder_that_is_not_a_run_is_a_one_line_error(tmp_path, capsys):
    assert main(["render", str(tmp_path), "-o", str(tmp_path / "x.exr")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"dofview: error: {tmp_path}: is a directory, neither a scene file nor a 3DGS run folder "
                   f"(no point_cloud/iteration_N/point_cloud.ply in it)")


def test_render_of_the_folder_is_view_0_at_its_own_size(run, tmp_path, capsys):
    out = tmp_path / "folder.exr"
    assert main(["render", str(run), "-o", str(out), "--focus", "3"]) == 0
    err = capsys.readouterr().err
    assert f"run folder {run}: iteration 30000 (of 7000, 30000); {run / 'cameras.json'}: 6 views" in err
    channels, header = read_exr(out)
    view0 = load_cameras_json(run / "cameras.json")[0]
    cam = json.loads(header["dofview:camera"])
    assert (cam["width"], cam["height"]) == (view0.width, view0.height) == (160, 120)
    assert np.allclose(cam["R"], view0.R) and np.allclose(cam["T"], view0.T)
    expected = render(load_scene(TWO_PLANES, progress=False), view0, Lens(3.0, 0.0))
    rgba = np.stack([channels[c] for c in "RGBA"], -1)
    assert psnr(rgba, expected.rgba, 1.0) >= 60.0
    assert channels["A"].mean() > 0.05  # the object is in view 0, not empty space


def test_iteration_option_and_explicit_cameras_win(run, tmp_path, capsys):
    other = tmp_path / "other.json"
    cams = load_cameras_json(run / "cameras.json")
    save_cameras_json([cams[3].resized(64, 48)], other)
    out = tmp_path / "x.exr"
    assert main(["render", str(run), "--iteration", "7000", "--cameras", str(other), "-o", str(out),
                 "--focus", "3"]) == 0
    _, header = read_exr(out)
    assert header["dofview:scene"] == str(run / "point_cloud" / "iteration_7000" / "point_cloud.ply")
    cam = json.loads(header["dofview:camera"])
    assert (cam["width"], cam["height"]) == (64, 48) and np.allclose(cam["R"], cams[3].R)
    assert "iteration 7000" in capsys.readouterr().err


def test_rig_centre_and_up_of_a_ring():
    cams = ring_cameras(TWO_PLANES)  # all looking at the middle of the robust box
    lo, hi = robust_box(load_scene(TWO_PLANES, progress=False))
    assert np.allclose(rig_centre(cams), (lo + hi) / 2, atol=1e-9)
    assert np.allclose(rig_up(cams), [0, -1, 0], atol=1e-9)
    # parallel axes (a forward-facing capture) have no nearest point
    assert rig_centre([cams[0], cams[0]]) is None


def test_a_folder_scene_passes_through(tmp_path):
    """An unbundled SOG (a folder holding meta.json) is a scene, not a run folder."""
    (tmp_path / "meta.json").write_text("{}")
    assert find_run(tmp_path).scene == tmp_path / "meta.json"


def test_a_cameras_json_near_a_plain_scene_file_is_not_its_cameras(tmp_path, capsys):
    """Issue 22: a cameras.json in the folder above scenes/ (or beside the file) made
    ``dofview render scenes/x.ply`` look through someone else's view 0, at nothing. Only the run
    folder layout, ROOT/point_cloud/iteration_N/point_cloud.ply beside ROOT/cameras.json, gives a
    file its cameras."""
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    scene = scenes / "two_planes.ply"
    scene.symlink_to(TWO_PLANES)
    away = [ring_cameras(TWO_PLANES)[0]]
    away = [look_at(away[0].centre, away[0].centre - away[0].forward, 160, 120)]  # looks away from the scene
    for folder in (tmp_path, scenes):
        save_cameras_json(away, folder / "cameras.json")
    assert find_run(scene) == RunFolder(scene)
    out = tmp_path / "x.exr"
    assert main(["render", str(scene), "-o", str(out), "--width", "64", "--height", "48"]) == 0
    err = capsys.readouterr().err
    assert "cameras.json" not in err and "up axis" in err  # framed from the scene itself
    assert read_exr(out)[0]["A"].mean() > 0.05
    # a point_cloud.ply outside the layout (no iteration_N above it) is a plain file too
    other = tmp_path / "point_cloud.ply"
    other.symlink_to(TWO_PLANES)
    assert find_run(other) == RunFolder(other)


def test_the_cameras_file_of_a_run_is_said_in_full(run, monkeypatch, capsys, tmp_path):
    monkeypatch.chdir(run.parent)
    found = find_run(run.name)
    assert found.cameras == run / "cameras.json" and found.cameras.is_absolute()
    assert main(["render", run.name, "-o", str(tmp_path / "x.exr"), "--focus", "3", "--width", "32"]) == 0
    assert f"{run / 'cameras.json'}: 6 views" in capsys.readouterr().err
