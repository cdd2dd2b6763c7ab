"""Streamed LOD sets (lod-meta.json + SOG chunks, dofview/io/lod.py), made by splat-transform from
scenes of the tests (tests/lod_sets.py): every level decodes as splat-transform decodes it and as
the source within the SOG quantisation; the level is chosen by --lod or the Gaussian budget; the
viewer's per-leaf choice is finer near and coarser far within the budget; bad sets are one-line
errors naming the file, exit 2, nothing written."""

from __future__ import annotations

import json
import shutil
import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest
from lod_sets import cards_set, sh_set

import dofview
from dofview.bench.formats import attribute_errors, match, splat_transform
from dofview.cli import main
from dofview.errors import DofviewError, DofviewWarning, SceneFormatError
from dofview.io import READERS, load_scene
from dofview.io.lod import DEFAULT_BUDGET, open_lod


def _copy(src: Path, dst: Path) -> Path:
    """A writable copy of a set's folder; returns its lod-meta.json."""
    shutil.copytree(src.parent, dst)
    return dst / "lod-meta.json"


def _splat_transform_level(path: Path, level: int, out: Path) -> dofview.GaussianScene:
    done = subprocess.run([splat_transform(), "-q", "-w", "-g", "cpu", str(path), "-L", str(level), str(out)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return load_scene(out, progress=False)


# ---- decoding -----------------------------------------------------------------------------------
@pytest.mark.parametrize("level", [0, 1])
def test_levels_decode_as_splat_transform_and_the_source(tmp_path, level):
    """Each level holds the Gaussians splat-transform decodes from the set (its own reader, -L), in
    the same order and to float precision, and they are the source PLY's within SOG quantisation
    (per-chunk 16-bit log positions, 256-entry codebooks: the bounds of test_made_sog_attributes)."""
    path = cards_set()
    scene = load_scene(path, progress=False, lod=level)
    theirs = _splat_transform_level(path, level, tmp_path / "theirs.ply")
    assert scene.count == theirs.count and scene.name == "set"
    for attr, tol in (("means", 1e-6), ("scales", 1e-6), ("opacities", 1e-6), ("sh_dc", 1e-6)):
        np.testing.assert_allclose(getattr(scene, attr), getattr(theirs, attr), rtol=1e-5, atol=tol)
    assert np.allclose(np.abs(np.sum(scene.quats * theirs.quats, axis=1)), 1.0, atol=1e-5)
    source = load_scene(path.parent.parent / f"level{level}.ply", progress=False)
    idx = match(scene, source)
    assert scene.count == source.count and len(np.unique(idx)) >= 0.99 * source.count
    errors = attribute_errors(scene, source.subset(idx))
    assert errors["position"] <= 2e-3 and errors["opacity"] <= 1.0 / 255 + 1e-6
    assert errors["rotation"] <= 0.04 and errors["log_scale"] <= 0.03
    assert errors["colour"] <= 0.01  # a 256-entry colour codebook per chunk (measured 0.003)


def test_sh_degree_and_environment():
    """Chunks of SH degree 1 and an environment of degree 0 (zero-padded) make one degree-1 scene;
    the environment belongs to every level; the set's folder opens as its lod-meta.json."""
    path = sh_set()
    lod = open_lod(path.parent)
    assert lod.levels == 2 and lod.counts.tolist() == [3000, 1000] and lod.environment_count == 200
    for level, n in ((0, 3000), (1, 1000)):
        scene = dofview.load(path.parent, lod=level)
        assert scene.count == n + 200 and scene.sh_degree == 1
        env = scene.subset(slice(n, None))  # the environment comes last
        assert np.all(env.means[:, 2] > 15) and not env.sh_rest.any()
    source = load_scene(path.parent.parent / "level0.ply", progress=False)
    scene = load_scene(path, progress=False, lod=0).subset(slice(0, 3000))
    idx = match(scene, source)
    errors = attribute_errors(scene, source.subset(idx))
    assert errors["sh_rest"] < 0.5  # a 256-entry palette of random vectors: coarse, but splat-transform's


def test_level_from_lod_or_budget(capsys):
    path = cards_set()
    lines = []
    assert load_scene(path, progress=False, report=lines.append).count == 19129  # within DEFAULT_BUDGET
    assert "2 levels: 19,129 / 9,565 Gaussians; level 0 (the finest within the budget of 3,000,000)" in lines[0]
    assert load_scene(path, progress=False, budget=10_000).count == 9565
    lines.clear()
    assert load_scene(path, progress=False, budget=100, report=lines.append).count == 9565
    assert "level 1 (the coarsest; every level exceeds the budget of 100)" in lines[0]
    with pytest.raises(DofviewError, match="--lod 2: the set has levels 0 .finest. to 1"):
        load_scene(path, progress=False, lod=2)
    assert READERS["lod-meta.json"] == "dofview.io.lod:read_lod" and DEFAULT_BUDGET >= 3_000_000


def test_cli_render_takes_lod_and_budget(tmp_path, capsys):
    path = cards_set()
    out = tmp_path / "a.exr"
    base = ["render", str(path.parent), "-o", str(out), "--width", "40", "--height", "30", "--focus", "4"]
    assert main(base + ["--budget", "10k"]) == 0 and out.exists()
    assert "level 1 (the finest within the budget of 10,000)" in capsys.readouterr().err
    assert main(base + ["--lod", "0"]) == 0
    assert "level 0 (--lod)" in capsys.readouterr().err
    for bad, needle in ((["--budget", "0"], "--budget must be a whole number"),
                        (["--budget", "1.5x"], "--budget must be a number of Gaussians"),
                        (["--lod", "-1"], "--lod must be ≥ 0")):
        with pytest.raises(SystemExit) as e:
            main(base + bad)
        assert e.value.code == 2 and needle in capsys.readouterr().err


# ---- choosing leaves (the viewer) ---------------------------------------------------------------
def test_select_is_finer_near_coarser_far_within_the_budget():
    lod = open_lod(cards_set())
    centres = lod.bounds.mean(axis=1)
    n = lod.refs[:, :, 2]
    for eye in (centres[0], centres[-1], np.array([0.0, 0.0, -50.0])):
        dist = np.linalg.norm(np.maximum(np.maximum(lod.bounds[:, 0] - eye, eye - lod.bounds[:, 1]), 0), axis=1)
        for budget in (n[:, 1].sum(), n[:, 1].sum() + 3000, n[:, 1].sum() + 6000, n[:, 0].sum(), 10**9):
            choice = lod.select(eye, int(budget))
            assert lod.selection_count(choice) <= budget
            order = np.argsort(dist, kind="stable")
            assert np.all(np.diff(choice[order]) >= 0)  # never finer farther away
            if 0 in choice and 1 in choice:  # a mixed choice spends the budget: one more leaf would not fit
                nxt = order[np.argmax(choice[order] == 1)]
                assert lod.selection_count(choice) + n[nxt, 0] - n[nxt, 1] > budget
        assert np.all(lod.select(eye, 10**9) == 0) and np.all(lod.select(eye, int(n[:, 1].sum())) == 1)
    # below the coarsest level's count the farthest leaves are left out
    choice = lod.select(centres[0], 5000)
    assert -1 in choice and np.all(choice[choice >= 0] == 1) and lod.selection_count(choice) <= 5000
    assert choice[np.argmin(np.linalg.norm(centres - centres[0], axis=1))] == 1


def test_gather_holds_each_leaf_at_its_level():
    """A mixed choice gathers exactly the Gaussians of the leaves' levels (compared as sets of rows
    of the level scenes), and lets go of the chunks it does not draw."""
    lod = open_lod(cards_set())
    levels = [lod.level_scene(0), lod.level_scene(1)]
    choice = np.array([i % 3 - 1 for i in range(lod.leaves)])  # -1, 0, 1, …
    got = lod.gather(choice)
    want = []
    for leaf, level in enumerate(choice):
        if level >= 0:
            f, o, c = lod.refs[leaf, level]
            first = sum(ch.count for i, ch in enumerate(lod.chunks) if ch is not None and ch.level == level and i < f)
            want.append(levels[level].means[first + o:first + o + c])
    rows = np.concatenate(want)
    assert got.count == len(rows) == lod.selection_count(choice)
    assert np.array_equal(np.unique(got.means, axis=0), np.unique(rows, axis=0))
    lod.keep_only(choice)
    kept = set(lod._decoded)
    assert kept == {int(f) for f, _, c in lod.refs[np.arange(lod.leaves), np.maximum(choice, 0)][choice >= 0] if c}


# ---- bad sets -----------------------------------------------------------------------------------
def _edit(meta: dict, how: str) -> dict:
    tree = meta["tree"]
    while "children" in tree:
        tree = tree["children"][0]
    if how == "counts":
        meta["counts"][0] += 1
    elif how == "outside":
        tree["lods"]["0"]["file"] = len(meta["filenames"])
    elif how == "overlap":
        tree["lods"]["0"]["offset"] += 1
    elif how == "level":
        meta["lodLevels"] = 1
    elif how == "total":
        meta["count"] = 5
    return meta


@pytest.mark.parametrize("how,needle", [
    ("counts", "counts [19130, 9565] are not the tree's ([19129, 9565])"),
    ("outside", "points at chunk 6; filenames lists 6"),
    ("overlap", "overlap or leave a gap"),
    ("level", "names level '1'; the set has 1 (lodLevels)"),
    ("total", "count 5 is not the tree's (28,694)"),
    ("json", "not valid JSON"),
    ("missing", "quats.webp is missing"),
    ("chunk_count", "meta.json, which holds"),
    ("truncated", "not a readable WebP image"),
])
def test_bad_sets_are_one_line_errors_and_write_nothing(tmp_path, capsys, how, needle):
    path = _copy(cards_set(), tmp_path / "set")
    meta = json.loads(path.read_text())
    chunk = path.parent / meta["filenames"][0]
    if how == "json":
        path.write_text(path.read_text()[:-20])
    elif how == "missing":
        (chunk.parent / "quats.webp").unlink()
    elif how == "chunk_count":  # the chunk's own meta.json says another count than the tree's ranges
        cm = json.loads(chunk.read_text())
        cm["count"] += 1
        chunk.write_text(json.dumps(cm))
    elif how == "truncated":
        webp = chunk.parent / "sh0.webp"
        webp.write_bytes(webp.read_bytes()[:200])
    else:
        path.write_text(json.dumps(_edit(meta, how)))
    out = tmp_path / "x.exr"
    code = main(["render", str(path), "-o", str(out), "--png", str(tmp_path / "x.png"), "--width", "16",
                 "--height", "12", "--focus", "4", "--lod", "0"])
    err = capsys.readouterr().err.strip().splitlines()
    errors = [line for line in err if line.startswith("dofview: error: ")]
    assert code == 2 and len(errors) == 1 and str(path) in errors[0] and needle in errors[0], err
    assert not out.exists() and not (tmp_path / "x.png").exists()


def test_a_truncated_chunk_of_a_level_not_read_is_no_error(tmp_path):
    """Chunks are decoded when their Gaussians are asked for: a bad chunk of level 0 spoils level 0,
    not level 1."""
    path = _copy(cards_set(), tmp_path / "set")
    lod = open_lod(path)
    chunk = next(c for c in lod.chunks if c is not None and c.level == 0)
    (chunk.path.parent / "means_l.webp").write_bytes(b"RIFF")
    assert load_scene(path, progress=False, lod=1).count == 9565
    with pytest.raises(SceneFormatError, match="means_l.webp is not a readable WebP image"):
        load_scene(path, progress=False, lod=0)


def test_non_finite_gaussians_of_a_chunk_are_dropped_with_a_warning(tmp_path):
    path = _copy(cards_set(), tmp_path / "set")
    chunk = path.parent / json.loads(path.read_text())["filenames"][0]
    cm = json.loads(chunk.read_text())
    cm["scales"]["codebook"] = cm["scales"]["codebook"][:-1] + [float("nan")]
    chunk.write_text(json.dumps(cm).replace("NaN", "1e999"))  # JSON has no NaN: an overflow to inf
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", DofviewWarning)
        scene = load_scene(path, progress=False, lod=0)
    assert any("dropped" in str(w.message) and str(chunk) in str(w.message) for w in caught)
    assert 0 < scene.count < 19129 and np.isfinite(scene.scales).all()


def test_bench_and_view_refuse_a_bad_set_in_one_line(tmp_path, capsys):
    path = _copy(cards_set(), tmp_path / "set")
    path.write_text(json.dumps(_edit(json.loads(path.read_text()), "outside")))
    for argv in (["bench", str(path.parent), "--quick", "--out", str(tmp_path / "o")],
                 ["render", str(path.parent), "-o", str(tmp_path / "x.exr"), "--budget", "1M"]):
        code = main(argv)
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and "points at chunk 6" in err[0], err
    assert not (tmp_path / "o").exists() and not (tmp_path / "x.exr").exists()
