"""`dofview render` sequences on a run folder built from tests/data/burger.ply: an 8-frame focus
pull to EXR + PNG + MP4, --resume, --range, a camera path through the training views, and one-line
errors for bad sequence arguments."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from conftest import psnr
from inria_folder import BURGER, make_run_folder, ring_cameras
from test_bad_input import run_cli

from dofview.cli import main
from dofview.io.cameras import load_cameras_json
from dofview.io.exr import read_exr
from dofview.io.png import read_png
from dofview.sequence import between, camera_path, focus_pull, slerp

FRAMES = 8
NEAR, FAR = 1.0, 4.0


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return make_run_folder(tmp_path_factory.mktemp("seq") / "burger", {30000: BURGER},
                           ring_cameras(BURGER, size=(96, 72)))


@pytest.fixture(scope="module")
def pull(run, tmp_path_factory):
    """The 8-frame focus pull from 1 to 4 units at A = 40, with PNGs and an MP4."""
    out = tmp_path_factory.mktemp("pull")
    argv = ["render", str(run), "--frames", str(FRAMES), "--focus", f"{NEAR}:{FAR}", "--aperture", "40",
            "-o", str(out / "pull_%04d.exr"), "--png", str(out / "pull_%04d.png"), "--video", str(out / "pull.mp4")]
    assert main(argv) == 0
    return out, argv


def test_focus_pull_writes_every_frame_with_its_focus_in_the_header(pull, run):
    out, _ = pull
    view0 = load_cameras_json(run / "cameras.json")[0]
    focuses = []
    for i in range(FRAMES):
        channels, header = read_exr(out / f"pull_{i:04d}.exr")
        assert channels["A"].shape == (72, 96) and (out / f"pull_{i:04d}.png").is_file()
        assert (header["dofview:frame"], header["dofview:frames"]) == (i, FRAMES)
        lens, cam = json.loads(header["dofview:lens"]), json.loads(header["dofview:camera"])
        assert lens["aperture"] == 40.0 and np.allclose(cam["R"], view0.R) and np.allclose(cam["T"], view0.T)
        focuses.append(lens["focus"])
    assert focuses[0] == pytest.approx(NEAR) and focuses[-1] == pytest.approx(FAR)
    assert np.allclose(np.diff(1 / np.array(focuses)), (1 / FAR - 1 / NEAR) / (FRAMES - 1))  # even in 1/z
    # the pull changes the picture: the first and last frames differ
    assert psnr(read_png(out / "pull_0000.png"), read_png(out / f"pull_{FRAMES - 1:04d}.png"), 255.0) < 35.0
    assert not list(out.glob("*.part"))


def test_video_holds_the_frames(pull):
    import imageio_ffmpeg

    out, _ = pull
    reader = imageio_ffmpeg.read_frames(str(out / "pull.mp4"))
    meta = reader.__next__()
    frames = [np.frombuffer(f, np.uint8).reshape(72, 96, 3) for f in reader]
    assert tuple(meta["size"]) == (96, 72) and len(frames) == FRAMES
    for i in (0, FRAMES - 1):  # H.264 at quality 8: close to the PNG, not equal
        assert psnr(frames[i], read_png(out / f"pull_{i:04d}.png"), 255.0) >= 30.0


def test_resume_renders_only_the_missing_frames(pull, capsys):
    out, argv = pull
    (out / "pull_0003.exr").unlink()
    before = {p.name: p.stat().st_mtime_ns for p in out.glob("pull_*.exr")}
    rc, err = run_cli(capsys, *argv, "--resume")
    assert rc == 0 and "1 rendered, 7 already there" in err
    assert (out / "pull_0003.exr").is_file()
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("pull_*.exr") if p.name in before} == before
    assert read_exr(out / "pull_0003.exr")[1]["dofview:frame"] == 3


def test_range_renders_only_its_frames(run, tmp_path, capsys):
    rc, err = run_cli(capsys, "render", run, "--frames", FRAMES, "--focus", f"{NEAR}:{FAR}", "--aperture", "40",
                      "--range", "2:4", "-o", tmp_path / "f_%03d.exr")
    assert rc == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f_002.exr", "f_003.exr", "f_004.exr"]
    header = read_exr(tmp_path / "f_003.exr")[1]
    assert json.loads(header["dofview:lens"])["focus"] == pytest.approx(focus_pull(NEAR, FAR, FRAMES)[3])
    # a farm's last chunk of fixed size may name frames past the end: it stops at the last frame
    rc, err = run_cli(capsys, "render", run, "--frames", FRAMES, "--focus", f"{NEAR}:{FAR}", "--aperture", "40",
                      "--range", "6:9", "-o", tmp_path / "f_%03d.exr")
    assert rc == 0 and "frames 6–7 of 8: 2 rendered" in err
    assert sorted(p.name for p in tmp_path.iterdir())[-2:] == ["f_006.exr", "f_007.exr"]


def test_camera_path_through_the_views(run, tmp_path, capsys):
    rc, err = run_cli(capsys, "render", run, "--views", "0:2", "--frames", "5", "--focus", "3",
                      "-o", tmp_path / "v_%02d.exr")
    assert rc == 0, err
    cams = load_cameras_json(run / "cameras.json")
    got = [json.loads(read_exr(tmp_path / f"v_{i:02d}.exr")[1]["dofview:camera"]) for i in range(5)]
    for i, view in ((0, 0), (2, 1), (4, 2)):  # frames 0, 2, 4 sit on views 0, 1, 2
        assert np.allclose(got[i]["R"], cams[view].R) and np.allclose(got[i]["T"], cams[view].T)
    mid = between(cams[0], cams[1], 0.5)
    assert np.allclose(got[1]["R"], mid.R) and np.allclose(got[1]["T"], mid.T)


def test_between_slerps_rotation_and_lerps_centre_and_intrinsics():
    a, b = ring_cameras(BURGER, n=4, size=(96, 72))[:2]
    b = b.resized(192, 144)  # another size: intrinsics compare at a's size
    b = type(b)(b.width, b.height, b.fx * 1.5, b.fy * 1.5, b.cx, b.cy, b.R, b.T)
    mid = between(a, b, 0.5)
    assert np.allclose(mid.R @ mid.R.T, np.eye(3), atol=1e-12)
    angle = lambda R0, R1: np.degrees(np.arccos(np.clip((np.trace(R0.T @ R1) - 1) / 2, -1, 1)))  # noqa: E731
    assert angle(a.R, mid.R) == pytest.approx(angle(mid.R, b.R)) == pytest.approx(angle(a.R, b.R) / 2)
    assert np.allclose(mid.centre, (a.centre + b.centre) / 2)
    assert mid.fx == pytest.approx(a.fx * 1.25) and (mid.width, mid.height) == (96, 72)
    assert np.allclose(slerp(a.R, b.R, 0.0), a.R) and np.allclose(slerp(a.R, b.R, 1.0), b.R)
    assert len(camera_path([a, b], 1, 0, 3, (96, 72))) == 3  # backwards along the views
    assert focus_pull(2.0, float("inf"), 3) == pytest.approx([2.0, 4.0, float("inf")])


@pytest.mark.parametrize("argv, needle", [
    (["--focus", "1:4"], "--focus A:B (a focus pull) needs --frames N"),
    (["--frames", "8", "--focus", "2"], "--frames N needs something to change"),
    (["--frames", "8", "--focus", "1:4", "-o", "{out}/x.exr"], "needs one frame number such as %04d"),
    (["--frames", "8", "--focus", "1:4", "--png", "{out}/x.png"], "--png of a sequence needs one frame number"),
    (["--frames", "8", "--focus", "1:4", "--range", "8:9"], "--range 8:9: the shot has frames 0…7"),
    (["--frames", "8", "--focus", "1:4", "--range", "5:2"], "the last frame comes before the first"),
    (["--frames", "8", "--focus", "1:x"], "argument --focus"),
    (["--views", "0:9"], "--views index 9 out of range (0…5)"),
    (["--views", "0-2"], "--views must be written I:J (view indices) or all"),
    (["--views", "0:2", "--eye=0,0,0", "--target=0,0,1"], "use either --views or --eye/--target"),
    (["--frames", "8", "--focus", "1:4", "--video", "{out}/v.avi"], "a video must end in one of .mp4, .mov, .mkv"),
    (["--frames", "8", "--focus", "1:4", "--range", "0:3", "--video", "{out}/v.mp4"], "--video needs the whole shot"),
])
def test_bad_sequence_arguments_are_one_line_errors(run, tmp_path, capsys, argv, needle):
    out = tmp_path / "out"
    out.mkdir()
    argv = [a.replace("{out}", str(out)) for a in argv]
    output = [] if "-o" in argv else ["-o", str(out / "f_%04d.exr")]
    rc, err = run_cli(capsys, "render", run, *output, "--aperture", "10", *argv)
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1 and lines[0].startswith("dofview: error: ") and needle in lines[0], err
    assert list(out.iterdir()) == []


def test_views_need_cameras(tmp_path, capsys):
    rc, err = run_cli(capsys, "render", BURGER, "--views", "all", "-o", tmp_path / "v_%02d.exr")
    assert rc == 2 and err.strip() == ("dofview: error: --views needs training views: --cameras cameras.json, "
                                       "or a run folder that has one")
    assert os.listdir(tmp_path) == []


def test_adaptive_tone_mapping_is_smoothed_along_a_sequence(run, tmp_path):
    """A sequence with an adaptive operator smooths each frame's statistics in time with Δt = 1/fps
    (StatsSmoother, as the viewer does); --stats joint holds one set for the whole shot."""
    import math

    from dofview.tonemap import OPERATORS
    from dofview.tonemap.stats import SMOOTHING_T0_S, frame_stats

    common = ["render", str(run), "--views", "0:3", "--frames", "3", "--aperture", "0", "--focus", "2",
              "--tonemap", "reinhard05", "--fps", "24"]
    assert main([*common, "-o", str(tmp_path / "s_%04d.exr")]) == 0
    keys, own = [], []
    for i in range(3):
        channels, header = read_exr(tmp_path / f"s_{i:04d}.exr")
        keys.append(json.loads(header["dofview:tonemap_stats"])["key_log2"])
        exposure = 2.0 ** header["dofview:exposure"]  # EV stops
        rgba = np.stack([channels[c] for c in "RGBA"], -1) / np.array([exposure, exposure, exposure, 1.0], np.float32)
        own.append(frame_stats(rgba, OPERATORS["reinhard05"]()).key)
    w = math.exp(-(1 / 24) / SMOOTHING_T0_S)
    assert keys[0] == pytest.approx(own[0], abs=1e-6)
    expected = own[0]
    for i in (1, 2):
        expected = w * expected + (1 - w) * own[i]
        assert keys[i] == pytest.approx(expected, abs=1e-4)
    assert abs(own[2] - own[0]) > 1e-3  # the views differ, so smoothing had something to do

    assert main([*common, "--stats", "joint", "-o", str(tmp_path / "j_%04d.exr")]) == 0
    joint = {read_exr(tmp_path / f"j_{i:04d}.exr")[1]["dofview:tonemap_stats"] for i in range(3)}
    assert len(joint) == 1


def test_resume_renders_again_the_frames_whose_lens_or_settings_changed(run, tmp_path, capsys):
    """--resume keeps only the frames whose headers record this command's camera, lens and settings."""
    shot = ["render", run, "--frames", 3, "--focus", f"{NEAR}:{FAR}", "-o", tmp_path / "f_%02d.exr", "--resume"]
    rc, err = run_cli(capsys, *shot, "--aperture", "40")
    assert rc == 0 and "3 rendered, 0 already there" in err, err
    rc, err = run_cli(capsys, *shot, "--aperture", "40")
    assert rc == 0 and "0 rendered, 3 already there" in err, err
    rc, err = run_cli(capsys, *shot, "--aperture", "60", "--range", "1:2")
    assert rc == 0 and "2 rendered (2 of them again: their recorded lens (2) differed from this command), " \
                       "0 already there" in err, err
    lenses = [json.loads(read_exr(tmp_path / f"f_{i:02d}.exr")[1]["dofview:lens"]) for i in range(3)]
    assert [lens["aperture"] for lens in lenses] == [40.0, 60.0, 60.0]
    rc, err = run_cli(capsys, *shot, "--aperture", "60", "--exposure", "1")
    assert rc == 0 and "3 rendered (3 of them again: their recorded lens (1), exposure (2) differed" in err, err


def test_blur_is_resolved_once_on_frame_0_whatever_the_range(run, tmp_path, capsys):
    """--blur in a focus pull: one strength for the shot, the same in a farm's chunk as in the whole."""
    shot = ["render", run, "--frames", 4, "--focus", f"{NEAR}:{FAR}", "--blur", "1%"]
    rc, err = run_cli(capsys, *shot, "-o", tmp_path / "all_%d.exr")
    assert rc == 0, err
    rc, err = run_cli(capsys, *shot, "-o", tmp_path / "chunk_%d.exr", "--range", "2:3")
    assert rc == 0, err
    whole = [json.loads(read_exr(tmp_path / f"all_{i}.exr")[1]["dofview:lens"]) for i in range(4)]
    chunk = [json.loads(read_exr(tmp_path / f"chunk_{i}.exr")[1]["dofview:lens"]) for i in (2, 3)]
    assert len({lens["aperture"] for lens in whole + chunk}) == 1 and whole[0]["aperture"] > 0
    assert whole[0]["asked"] == "--blur 1%"
