"""SfM points: COLMAP text/binary and .ply readers, dataset discovery, the trainer's start from them,
and make-dataset --points (dofview/train/points.py, dataset.py, model.py, generate.py)."""

import json
import shutil
import struct

import numpy as np
import plyfile
import pytest

torch = pytest.importorskip("torch")

from dofview.cli import main  # noqa: E402
from dofview.errors import DofviewError  # noqa: E402
from dofview.io import load_scene  # noqa: E402
from dofview.train.dataset import load_dataset  # noqa: E402
from dofview.train.generate import Capture, generate  # noqa: E402
from dofview.train.model import initial_model  # noqa: E402
from dofview.train.points import (nearest_distance, read_colmap_binary, read_colmap_text,  # noqa: E402
                                  read_points, write_colmap_text)

POSITIONS = np.array([[0.5, -1.25, 3.0], [1e-3, 2.0, -4.5], [7.0, 0.0, 1.0 / 3.0]])
COLOURS = np.array([[255, 0, 10], [1, 2, 3], [128, 64, 32]], np.uint8)
TRACKS = [[(1, 5), (2, 7)], [], [(3, 1), (1, 0), (4, 9)]]


def _text(path, tracks=TRACKS):
    """COLMAP's text layout, written here by hand (comments, ids not in order, tracks)."""
    lines = ["# 3D point list with one line of data per point:", "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[]"]
    for i, (p, c, t) in enumerate(zip(POSITIONS.tolist(), COLOURS.tolist(), tracks)):
        track = " ".join(f"{a} {b}" for a, b in t)
        lines.append(f"{10 + 3 * i} {p[0]!r} {p[1]!r} {p[2]!r} {c[0]} {c[1]} {c[2]} 0.75 {track}".rstrip())
    path.write_text("\n".join(lines) + "\n\n")
    return path


def _binary(path, tracks=TRACKS):
    """COLMAP's binary layout, written here with struct (little-endian)."""
    out = struct.pack("<Q", len(POSITIONS))
    for i, (p, c, t) in enumerate(zip(POSITIONS, COLOURS, tracks)):
        out += struct.pack("<Q3d3BdQ", 10 + 3 * i, *p, *c, 0.75, len(t))
        out += b"".join(struct.pack("<ii", a, b) for a, b in t)
    path.write_bytes(out)
    return path


def test_colmap_text_and_binary_read_the_same_points(tmp_path):
    text = read_colmap_text(_text(tmp_path / "points3D.txt"))
    binary = read_colmap_binary(_binary(tmp_path / "points3D.bin"))
    for cloud in (text, binary):
        np.testing.assert_array_equal(cloud.positions, POSITIONS)  # repr() keeps every bit in the text
        np.testing.assert_array_equal(cloud.colours * 255, COLOURS)
    # our writer (make-dataset's) reads back the same
    write_colmap_text(tmp_path / "ours.txt", POSITIONS, COLOURS)
    ours = read_points(tmp_path / "ours.txt")
    np.testing.assert_array_equal(ours.positions, POSITIONS)
    np.testing.assert_array_equal(ours.colours, text.colours)


def test_ply_points_with_and_without_colour(tmp_path):
    rows = np.array([(*p, *c) for p, c in zip(POSITIONS, COLOURS)],
                    dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("red", "u1"), ("green", "u1"), ("blue", "u1")])
    plyfile.PlyData([plyfile.PlyElement.describe(rows, "vertex")]).write(str(tmp_path / "pc.ply"))
    cloud = read_points(tmp_path / "pc.ply")
    np.testing.assert_allclose(cloud.positions, POSITIONS.astype(np.float32))
    np.testing.assert_array_equal(cloud.colours * 255, COLOURS)
    plain = np.array([tuple(p) for p in POSITIONS], dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    plyfile.PlyData([plyfile.PlyElement.describe(plain, "vertex")]).write(str(tmp_path / "plain.ply"))
    assert read_points(tmp_path / "plain.ply").colours is None


def _bad_files(tmp_path):
    good = _binary(tmp_path / "good.bin").read_bytes()
    cases = {
        "cut.bin": good[:-5],  # the last track pair cut short
        "extra.bin": good + b"\0",
        "count.bin": struct.pack("<Q", 10 ** 9) + good[8:],
        "tiny.bin": b"\1\0",
        "empty.txt": b"# nothing\n",
        "fields.txt": b"1 0.5 0.5 0.5 10 10 10\n",  # no error value
        "colour.txt": b"1 0.5 0.5 0.5 300 10 10 0.1\n",
        "nan.txt": b"1 nan 0.5 0.5 10 10 10 0.1\n",
        "word.txt": b"1 a b c 10 10 10 0.1\n",
        "binary.txt": b"\xff\xfe\x00garbage",
        "points.xyz": b"0 0 0\n",
        "broken.ply": b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nend_header\n1\n",
        "noxyz.ply": b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float q\nend_header\n1\n",
    }
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
    return [tmp_path / n for n in cases] + [tmp_path / "missing.txt"]


def test_bad_points_files_are_named_errors(tmp_path):
    for path in _bad_files(tmp_path):
        with pytest.raises(DofviewError) as e:
            read_points(path)
        assert str(path) in str(e.value) and "\n" not in str(e.value), path.name


def _dataset(tmp_path, points=0, views=4):
    from test_train import hdr_scene

    ds = tmp_path / "ds"
    generate(hdr_scene(), ds, Capture(views=views, held_out=1, width=32, height=24, points=points), eye=(0, 0, 0),
             target=(0, 0, 4.5), progress=False)
    return ds


def test_make_dataset_points_lie_on_the_scene(tmp_path):
    from test_train import hdr_scene

    ds = _dataset(tmp_path, points=200)
    assert json.loads((ds / "transforms.json").read_text())["generator"]["points"] == 200
    cloud = load_dataset(ds).points
    assert cloud is not None and cloud.path == ds / "sparse" / "0" / "points3D.txt" and len(cloud.positions) == 200
    scene = hdr_scene()
    gap = np.linalg.norm(cloud.positions[:, None] - scene.means[None], axis=2).min(1)
    fx = 32 / (2 * np.tan(np.radians(Capture().fov_deg) / 2))
    sigma = np.linalg.norm(cloud.positions, axis=1) / fx  # one pixel at the distance from the eye (0, 0, 0)
    assert 0 < np.median(gap / sigma) < 3 and np.all(gap < 6 * sigma)  # ~1 px of noise in 3-D
    assert len(np.unique(cloud.colours, axis=0)) > 3  # coloured from the scene


def test_dataset_finds_points_where_named_or_beside(tmp_path):
    ds = _dataset(tmp_path, points=0)
    assert load_dataset(ds).points is None  # the random start stays
    doc = json.loads((ds / "transforms.json").read_text())
    (ds / "colmap" / "sparse" / "0").mkdir(parents=True)
    _binary(ds / "colmap" / "sparse" / "0" / "points3D.bin")
    np.testing.assert_array_equal(load_dataset(ds).points.positions, POSITIONS)
    # nerfstudio: raw COLMAP points are moved by applied_transform into the frame of the poses
    m = [[0.0, 1.0, 0.0, 1.0], [1.0, 0.0, 0.0, 2.0], [0.0, 0.0, -1.0, 3.0]]
    (ds / "transforms.json").write_text(json.dumps({**doc, "applied_transform": m}))
    moved = load_dataset(ds).points.positions
    np.testing.assert_allclose(moved, POSITIONS @ np.array(m)[:, :3].T + [1.0, 2.0, 3.0])
    # a file named in transforms.json wins, as it stands
    _text(ds / "mine.txt")
    for key in ("points3D", "ply_file_path"):
        (ds / "transforms.json").write_text(json.dumps({**doc, key: "mine.txt", "applied_transform": m}))
        cloud = load_dataset(ds).points
        assert cloud.path == ds / "mine.txt"
        np.testing.assert_array_equal(cloud.positions, POSITIONS)
    (ds / "transforms.json").write_text(json.dumps({**doc, "points3D": 3}))
    with pytest.raises(DofviewError, match="points3D must name a points file"):
        load_dataset(ds)


def test_start_from_points(tmp_path):
    from test_train import LAMP, LAMP_RADIANCE

    ds = _dataset(tmp_path, points=300, views=12)
    data = load_dataset(ds)
    from dofview.train.dataset import load_photo

    photos = [load_photo(s) for s in data.shots]
    rng = np.random.default_rng(0)
    model = initial_model(data, photos, 5, True, rng, torch.device("cpu"), max_count=1000)
    means = model.params["means"].detach().numpy()
    np.testing.assert_allclose(means, data.points.positions.astype(np.float32))  # every point, none random
    # scale: RMS distance to the 3 nearest others, against a brute-force count
    d = np.linalg.norm(data.points.positions[:, None] - data.points.positions[None], axis=2)
    np.fill_diagonal(d, np.inf)
    brute = np.sqrt((np.sort(d, 1)[:, :3] ** 2).mean(1))
    np.testing.assert_allclose(np.exp(model.params["log_scales"].detach().numpy()[:, 0]), brute, rtol=1e-5)
    np.testing.assert_allclose(nearest_distance(data.points.positions), brute)
    # colour: radiance seen in the photos; the lamp's points get the lamp's (≥ 200× the wall)
    colours = np.exp(model.params["log_colours"].detach().numpy())
    lamp = np.linalg.norm(data.points.positions - LAMP, axis=1) < 0.15
    assert lamp.sum() >= 1
    ratio = np.median(colours[lamp], axis=0) / LAMP_RADIANCE
    assert np.all((ratio > 0.5) & (ratio < 1.5)), ratio
    assert np.median(colours[~lamp]) < 0.5  # the walls and the card stay dim
    # more points than the cap: a random subset of them
    small = initial_model(data, photos, 5, True, rng, torch.device("cpu"), max_count=100)
    assert small.count == 100
    assert np.isin(small.params["means"].detach().numpy(), means).all()


def test_train_from_points_end_to_end(tmp_path, capsys):
    ds = tmp_path / "ds"
    from test_train import hdr_scene
    from dofview.io.ply import write_ply

    write_ply(hdr_scene(), tmp_path / "hdr.ply")
    assert main(["make-dataset", str(tmp_path / "hdr.ply"), "-o", str(ds), "--eye", "0,0,0", "--target", "0,0,4.5",
                 "--views", "4", "--held-out", "1", "--width", "32", "--height", "24", "--points", "150"]) == 0
    out, log = tmp_path / "p.ply", tmp_path / "p.json"
    assert main(["train", str(ds), "-o", str(out), "--iterations", "20", "--warmup", "10", "--gaussians", "7",
                 "--checkpoint-every", "0", "--log", str(log)]) == 0
    history = json.loads(log.read_text())["history"]
    assert history[0]["gaussians"] == 150  # the points, not --gaussians random ones
    assert load_scene(out, progress=False).count == 150
    capsys.readouterr()
    # a bad points file: one line naming it, exit 2, nothing written
    shutil.rmtree(ds / "sparse")
    (ds / "sparse" / "0").mkdir(parents=True)
    (ds / "sparse" / "0" / "points3D.bin").write_bytes(b"\5\0\0\0\0\0\0\0short")
    out2 = tmp_path / "bad.ply"
    assert main(["train", str(ds), "-o", str(out2), "--iterations", "2", "--checkpoint-every", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "points3D.bin" in err and err.startswith("dofview: error: ")
    assert not out2.exists() and not out2.with_suffix(".ckpt").exists()
