"""Distribution formats (issue 13): Niantic .spz (v2–v4, read and write), PlayCanvas .compressed.ply
and .sog. Checked on real files made elsewhere (tests/data/README.md), on files made from the bundled
samples by the formats' own tool (PlayCanvas splat-transform, installed by scripts/setup.sh: these
tests fail, not skip, without it), and against renders of the source .ply.

Tolerances are the formats' quantisation steps (half a step, plus float32 slack) unless stated.
"""

import gzip
import json
import struct
import warnings
import zipfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import plyfile
import pytest
from conftest import random_scene
from inria_folder import SCENES as DATA

import dofview
from dofview.bench.formats import (
    attribute_errors,
    convert,
    match,
    splat_transform,
    view_psnr,
)
from dofview.bench.metrics import psnr
from dofview.camera import look_at
from dofview.cli import main
from dofview.errors import DofviewError, DofviewWarning, SceneFormatError
from dofview.io import load_scene, save_scene
from dofview.io.compressed_ply import read_compressed_ply
from dofview.io.ply import scene_rows, write_ply
from dofview.io.sog import read_sog
from dofview.io.spz import (
    SH_PARITY,
    _parse_v4,
    axis_signs,
    flip_axes,
    read_spz,
    write_spz,
)
from dofview.scene import SH_C0, GaussianScene

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "samples"
SPZ_COLOUR_TOP = 127.5 / (0.15 * 255)  # the largest DC term an .spz colour byte holds



def rotation_tol(half_step: float) -> float:
    """Largest rotation angle (radians) when the three stored quaternion components are each off by
    ``half_step``: |Δ| ≤ √3·h for them, and the rebuilt largest one m ≥ |others|/√3 moves by at
    most √3 times that, so |Δq| ≤ 2√3·h and the angle ≤ 2·|Δq|."""
    return 4 * np.sqrt(3) * half_step + 1e-4


# Half a quantisation step of each .spz field: positions 12 fractional bits, log-scales 1/16,
# opacity and colour 1/255 (colour on the 0.15 scale), rotation 9 bits of |q|·√2, SH 5 bits
# (degree 1) and 4 bits (degrees 2–3) of v·128, after rounding to 8 bits (half a step more).
SPZ_TOL = {"position": 0.5 / 4096 + 1e-6, "log_scale": 0.5 / 16 + 1e-5, "opacity": 0.5 / 255 + 1e-6,
           "colour": 0.5 / 255 / 0.15 * SH_C0 + 1e-6, "rotation": rotation_tol(0.5 * np.sqrt(0.5) / 511),
           "sh_rest": (0.5 * 16 + 0.5) / 128 + 1e-6}


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """samples/{cards,lamp}.ply converted by splat-transform into each format: {(name, ext): path}."""
    splat_transform() or pytest.fail("splat-transform is not installed: run scripts/setup.sh "
                                     "(it installs @playcanvas/splat-transform into .tools with npm)")
    folder = tmp_path_factory.mktemp("made")
    return {(name, ext): convert(SAMPLES / f"{name}.ply", folder / f"{name}.{ext}")
            for name in ("cards", "lamp") for ext in ("spz", "compressed.ply", "sog")}


def _finite(scene: GaussianScene) -> bool:
    arrays = [scene.means, scene.quats, scene.scales, scene.opacities, scene.sh_dc]
    arrays += [] if scene.sh_rest is None else [scene.sh_rest]
    return all(np.isfinite(a).all() for a in arrays) and bool((scene.scales > 0).all())


# ---- the real files made elsewhere (tests/data) ---------------------------------------------------
def test_biker_spz_v4_is_upright_in_dofview_axes():
    """biker.spz (v4, zstd): 152,746 Gaussians, SH 0. Stored in the spec's RUB, so read into
    dofview's RDF the rider stands on y = 0 and rises towards −y (up is −y); taken as stored
    (``spz_axes="rdf"``) the same data is mirrored in y and z."""
    lines = []
    scene = read_spz(DATA / "biker.spz", report=lines.append)
    assert scene.count == 152_746 and scene.sh_degree == 0 and _finite(scene)
    np.testing.assert_allclose(np.linalg.norm(scene.quats, axis=1), 1.0, atol=1e-5)
    y = scene.means[:, 1]
    top, bottom = np.percentile(y, [99.5, 0.5])  # feet at the top of the y range, head ≈ 3 units above
    assert abs(top) < 0.05 and bottom < -2.5
    assert lines == [("biker.spz: SPZ v4, data read as RUB (the SPZ spec's default), turned into dofview's RDF; "
                      "--spz-axes rdf reads it the other way")]
    raw = read_spz(DATA / "biker.spz", spz_axes="rdf")
    np.testing.assert_array_equal(raw.means * [1, -1, -1], scene.means)


def test_tap_spz_v2_gzip_with_sh3_and_antialiasing():
    with pytest.warns(DofviewWarning, match="antialiasing"):
        scene = read_spz(DATA / "tap.spz")
    assert scene.count == 132_432 and scene.sh_degree == 3 and _finite(scene)
    np.testing.assert_allclose(np.linalg.norm(scene.quats, axis=1), 1.0, atol=1e-5)
    assert np.abs(scene.sh_rest).max() <= 1.0 and (scene.sh_rest != 0).any()


def test_guitar_compressed_ply_also_under_a_plain_ply_name(tmp_path):
    scene = load_scene(DATA / "guitar.compressed.ply", progress=False)
    assert scene.count == 90_854 and scene.sh_degree == 0 and _finite(scene)
    assert scene.opacities.min() >= 0 and scene.opacities.max() <= 1
    renamed = tmp_path / "guitar.ply"
    renamed.write_bytes((DATA / "guitar.compressed.ply").read_bytes())
    again = load_scene(renamed, progress=False)  # the .ply reader sees the chunk element
    for a in ("means", "quats", "scales", "opacities", "sh_dc"):
        np.testing.assert_array_equal(getattr(again, a), getattr(scene, a))


def test_ply_converted_by_splat_transform_keeps_its_fully_opaque_gaussians(tmp_path):
    """splat-transform (the field's converter) decompresses an 8-bit opacity of 255 to the logit
    +inf (sigmoid(+inf) = 1): 667 of guitar's 90,854 Gaussians. They are fully opaque Gaussians, not
    damage: the .ply reads as its compressed source does, every Gaussian and no warning (float32
    round trip of the logit and the log-scale: 1e-6)."""
    splat_transform() or pytest.fail("splat-transform is not installed: run scripts/setup.sh")
    source = DATA / "guitar.compressed.ply"
    converted = convert(source, tmp_path / "guitar.ply")
    logits = np.asarray(plyfile.PlyData.read(str(converted))["vertex"]["opacity"])
    assert np.isposinf(logits).sum() == 667 and not np.isnan(logits).any()
    ref = load_scene(source, progress=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DofviewWarning)
        scene = load_scene(converted, progress=False)
    assert scene.count == ref.count == 90_854
    np.testing.assert_array_equal(scene.opacities[np.isposinf(logits)], 1.0)
    np.testing.assert_array_equal(scene.means, ref.means)
    np.testing.assert_array_equal(scene.sh_dc, ref.sh_dc)
    np.testing.assert_allclose(scene.opacities, ref.opacities, atol=1e-6)
    np.testing.assert_allclose(scene.scales, ref.scales, rtol=1e-5)
    np.testing.assert_allclose(np.abs(np.sum(scene.quats * ref.quats, axis=1)), 1.0, atol=1e-6)


def test_infinite_opacity_logits_are_the_limits_and_only_damage_is_dropped(tmp_path):
    """An opacity logit of +inf is opacity 1 and −inf opacity 0 (kept); a NaN logit, or an infinite
    position or scale, has no limit that means anything and is dropped with the one warning."""
    scene = random_scene(n=40, degree=1, seed=9)
    rows = scene_rows(scene)
    rows["opacity"][[3, 4]] = np.inf
    rows["opacity"][7] = -np.inf
    rows["opacity"][11] = np.nan
    rows["x"][12] = np.inf
    rows["scale_1"][13] = -np.inf
    path = tmp_path / "limits.ply"
    path.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 40\n"
                     + b"".join(f"property float {n}\n".encode() for n in rows.dtype.names)
                     + b"end_header\n" + rows.tobytes())
    with pytest.warns(DofviewWarning, match="dropped 3 of 40 Gaussians with NaN or infinite values"):
        loaded = load_scene(path, progress=False)
    keep = np.setdiff1d(np.arange(40), [11, 12, 13])
    assert loaded.count == 37
    opacity = dict(zip(keep.tolist(), loaded.opacities.tolist()))
    assert opacity[3] == opacity[4] == 1.0 and opacity[7] == 0.0
    np.testing.assert_array_equal(loaded.means, scene.means[keep])


# ---- files made by splat-transform from the samples -----------------------------------------------
# Image PSNR at view 0, 160×120, against the source .ply (docs/FORMATS.md has the measured values).
# cards: coplanar splats on flat cards reorder under any position change (a 1e-5 jitter alone gives
# 35 dB), so every format lands at 24–28 dB; lamp: .spz clips its HDR colours (DC ≤ 3.33, the lamp
# reaches 388), the others keep them.
MIN_PSNR = {("cards", "spz"): 23.0, ("cards", "compressed.ply"): 25.0, ("cards", "sog"): 24.0,
            ("lamp", "spz"): 25.0, ("lamp", "compressed.ply"): 60.0, ("lamp", "sog"): 60.0}


@pytest.mark.parametrize("name,ext", sorted(MIN_PSNR))
def test_made_by_splat_transform_renders_like_the_source(made, name, ext):
    ref = dofview.load(SAMPLES / f"{name}.ply")
    scene = dofview.load(made[name, ext], colour_space=ref.colour_space, spz_axes="rdf" if ext == "spz" else None)
    assert scene.count == ref.count and scene.sh_degree == ref.sh_degree and _finite(scene)
    assert view_psnr(scene, ref, SAMPLES / f"{name}_cameras.json") >= MIN_PSNR[name, ext]


def _in_range(ref: GaussianScene) -> np.ndarray:
    """Gaussians whose DC term fits every format's colour range (lamp's HDR emitter does not)."""
    return np.all(np.abs(ref.sh_dc) < SPZ_COLOUR_TOP, axis=1)


@pytest.mark.parametrize("name", ["cards", "lamp"])
def test_made_spz_attributes_within_quantisation(made, name):
    """splat-transform writes .spz with Niantic's own library: same order, every field within
    half a step (colour where it fits the format's range)."""
    ref = dofview.load(SAMPLES / f"{name}.ply")
    scene = dofview.load(made[name, "spz"], spz_axes="rdf")
    keep = _in_range(ref)
    errors = attribute_errors(scene.subset(keep), ref.subset(keep))
    for field, err in errors.items():
        assert err <= SPZ_TOL[field], (field, err)


@pytest.mark.parametrize("name", ["cards", "lamp"])
def test_made_compressed_ply_attributes_within_quantisation(made, name, tmp_path):
    """Each Gaussian (matched by position: the file is in Morton order) is within half a step of
    its chunk's range: 11/10/11-bit positions and log-scales, 8-bit colour and opacity, 10-bit
    rotation components, 8-bit SH over [−4, 4]."""
    ref = dofview.load(SAMPLES / f"{name}.ply")
    scene = read_compressed_ply(made[name, "compressed.ply"])
    src = ref.subset(match(scene, ref))
    assert len(np.unique(match(scene, ref))) == ref.count  # one to one

    def half_steps(values: np.ndarray, levels) -> np.ndarray:
        """Half a step of each Gaussian's chunk range (min…max over its 256, from the source)."""
        span = np.empty_like(values, dtype=np.float64)
        for c in range(0, len(values), 256):
            span[c:c + 256] = values[c:c + 256].max(0) - values[c:c + 256].min(0)
        return 0.5 * span / np.asarray(levels)

    assert np.all(np.abs(scene.means - src.means) <= half_steps(src.means, [2047, 1023, 2047]) + 1e-5)
    colour = SH_C0 * src.sh_dc.astype(np.float64) + 0.5
    assert np.all(np.abs(SH_C0 * scene.sh_dc + 0.5 - colour) <= half_steps(colour, 255) + 1e-5)
    errors = attribute_errors(scene, src)
    assert errors["opacity"] <= 0.5 / 255 + 1e-6
    assert errors["rotation"] <= rotation_tol(0.5 * np.sqrt(2) / 1023)
    assert errors["log_scale"] <= 0.01
    if ref.sh_rest is not None:
        assert errors["sh_rest"] <= 8.0 / 256 + 1e-6  # truncation: a whole step


@pytest.mark.parametrize("name", ["cards", "lamp"])
def test_made_sog_attributes(made, name):
    """SOG: 16-bit log-transformed positions, 256-entry codebooks (scales, colours, SH palette),
    8-bit opacity and quaternion components. Bounds here are the measured errors (docs/FORMATS.md)
    with about 2× margin: codebook errors depend on the clustering, not on a fixed step."""
    ref = dofview.load(SAMPLES / f"{name}.ply")
    scene = read_sog(made[name, "sog"])
    idx = match(scene, ref)
    assert len(np.unique(idx)) >= 0.99 * ref.count
    errors = attribute_errors(scene, ref.subset(idx))
    assert errors["position"] <= 2e-3 and errors["opacity"] <= 1.0 / 255 + 1e-6
    assert errors["rotation"] <= 0.04 and errors["log_scale"] <= 0.03
    if ref.sh_rest is not None:
        assert errors["sh_rest"] <= 0.01


def test_sog_bundle_folder_and_meta_json_read_alike(tmp_path):
    """An unbundled SOG (meta.json + WebP files in a folder) opens by its folder or its meta.json and
    equals the zip bundle; SH degree 2 goes through the palette."""
    ply = tmp_path / "small.ply"
    write_ply(random_scene(n=3000, degree=2, seed=3), ply)
    bundle = convert(ply, tmp_path / "small.sog")
    with zipfile.ZipFile(bundle) as z:
        z.extractall(tmp_path / "loose")
    a = load_scene(bundle, progress=False)
    for other in (tmp_path / "loose", tmp_path / "loose" / "meta.json"):
        b = load_scene(other, progress=False)
        assert b.name == "loose" and b.sh_degree == 2
        for attr in ("means", "quats", "scales", "opacities", "sh_dc", "sh_rest"):
            np.testing.assert_array_equal(getattr(a, attr), getattr(b, attr))
    ref = dofview.load(ply)
    errors = attribute_errors(a, ref.subset(match(a, ref)))
    assert errors["sh_rest"] < 0.5  # a 256-entry palette for 3000 random vectors: coarse, but theirs
    (tmp_path / "written").mkdir()  # splat-transform's own unbundled output (its k-means differs per run)
    c = load_scene(convert(ply, tmp_path / "written" / "meta.json"), progress=False)
    np.testing.assert_array_equal(c.means, a.means)
    assert c.sh_degree == 2 and _finite(c)


# ---- the .spz writer ----------------------------------------------------------------------------
def _spz_blocks(path: Path) -> list[bytes]:
    return _parse_v4(path, path.read_bytes())[5]


def test_dofview_spz_writer_matches_niantics_encoder(made, tmp_path):
    """dofview's .spz of lamp (SH 3), stored in PLY axes as splat-transform stores them, holds the
    same bytes as splat-transform's (Niantic's library) in every attribute stream: at most one
    code apart where float rounding differs, and nearly all equal."""
    ours = tmp_path / "lamp.spz"
    write_spz(dofview.load(SAMPLES / "lamp.ply"), ours, spz_axes="rdf")
    theirs = made["lamp", "spz"]
    for i, (a, b) in enumerate(zip(_spz_blocks(ours), _spz_blocks(theirs))):
        x, y = np.frombuffer(a, np.uint8).astype(int), np.frombuffer(b, np.uint8).astype(int)
        assert x.shape == y.shape
        if i == 4:  # rotations: compare the decoded quaternions instead of packed bits
            continue
        assert np.abs(x - y).max() <= 1 and (x == y).mean() >= 0.999, i
    a, b = read_spz(ours, spz_axes="rdf"), read_spz(theirs, spz_axes="rdf")
    assert attribute_errors(a, b)["rotation"] <= 2e-3


@pytest.mark.parametrize("degree", [0, 1, 3])
def test_spz_round_trip_within_quantisation(tmp_path, degree):
    scene = random_scene(n=3000, degree=degree, seed=degree)
    path = tmp_path / "s.spz"
    save_scene(scene, path)
    assert path.read_bytes()[:4] == b"NGSP"
    back = load_scene(path, progress=False)
    assert back.count == scene.count and back.sh_degree == degree
    keep = _in_range(scene)
    assert keep.mean() > 0.9
    for field, err in attribute_errors(back.subset(keep), scene.subset(keep)).items():
        assert err <= SPZ_TOL[field], (field, err)
    # the file holds the spec's RUB axes: read as stored, y and z come out negated
    raw = read_spz(path, spz_axes="rdf")
    np.testing.assert_array_equal(raw.means * [1, -1, -1], back.means)


def test_spz_through_splat_transform(tmp_path):
    """splat-transform reads dofview's .spz: written in PLY axes it converts back to the same
    Gaussians; written in the spec's RUB (dofview's default) it keeps them as stored, i.e. flipped
    — the disagreement the --spz-axes option exists for."""
    scene = random_scene(n=2000, degree=3, seed=7)
    for axes in ("rdf", "rub"):
        spz = tmp_path / f"{axes}.spz"
        write_spz(scene, spz, spz_axes=axes)
        ours = read_spz(spz, spz_axes="rdf")  # exactly what the file holds
        theirs = dofview.load(convert(spz, tmp_path / f"{axes}.ply"))
        errors = attribute_errors(theirs, ours)
        assert errors["position"] <= 1e-6 and errors["log_scale"] <= 1e-4 and errors["sh_rest"] <= 1e-6
        assert errors["rotation"] <= 1e-3 and errors["colour"] <= 1e-5 and errors["opacity"] <= 1e-5
        if axes == "rub":
            assert np.abs(theirs.means * [1, -1, -1] - scene.means).max() <= 2e-4


def test_splat_transform_spz_read_in_ply_axes_matches_the_source(made):
    """The --spz-axes rdf reading of splat-transform's .spz is the source .ply (within the format);
    the spec reading of it is the source turned 180° about x."""
    ref = dofview.load(SAMPLES / "lamp.ply")
    as_stored = dofview.load(made["lamp", "spz"], spz_axes="rdf")
    spec = dofview.load(made["lamp", "spz"])
    assert attribute_errors(as_stored, ref)["position"] <= SPZ_TOL["position"]
    np.testing.assert_allclose(spec.means, ref.means * [1, -1, -1], atol=SPZ_TOL["position"])


# ---- the axis flip of SH, against a render ----------------------------------------------------------
def _flipped(scene: GaussianScene, skip_degree: int | None = None) -> GaussianScene:
    """``scene`` turned 180° about x (y, z negated); ``skip_degree`` leaves that SH degree's
    coefficients unflipped (a deliberately wrong conversion)."""
    means, quats, rest = flip_axes(scene.means.astype(np.float64), scene.unit_quats(),
                                   scene.sh_rest.astype(np.float64), axis_signs("rub"))
    if skip_degree is not None:
        band = slice(skip_degree ** 2 - 1, (skip_degree + 1) ** 2 - 1)
        rest[:, band] = scene.sh_rest[:, band]
    return GaussianScene(means=means, quats=quats, scales=scene.scales, opacities=scene.opacities,
                         sh_dc=scene.sh_dc, sh_rest=rest, colour_space=scene.colour_space)


def test_sh_sign_flips_per_degree_against_a_render():
    """A scene turned 180° about x, seen by the camera turned with it, is the same picture: with
    every degree's SH signs flipped as SH_PARITY says the render matches to ≥ 60 dB, and leaving
    any one degree unflipped is visibly wrong (< 45 dB) — so each degree's signs are tested."""
    scene = random_scene(n=1500, degree=3, seed=5)
    scene.sh_rest *= 3.0  # strong view dependence
    camera = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 5.0), 160, 120, 50.0)
    turned = replace(camera, R=camera.R @ np.diag([1.0, -1.0, -1.0]))
    ref = dofview.render(scene, camera).rgba
    peak = max(1.0, float(ref.max()))
    assert psnr(dofview.render(_flipped(scene), turned).rgba, ref, peak) >= 60.0
    for degree in (1, 2, 3):
        assert psnr(dofview.render(_flipped(scene, degree), turned).rgba, ref, peak) < 45.0, degree
    assert SH_PARITY.shape == (15, 3)


# ---- the command line ------------------------------------------------------------------------------
def test_cli_renders_spz_and_says_which_axes(tmp_path, capsys):
    out = tmp_path / "b.exr"
    argv = ["render", str(DATA / "biker.spz"), "-o", str(out), "--width", "40", "--height", "30", "--up=-y"]
    assert main(argv) == 0 and out.exists()
    assert "data read as RUB (the SPZ spec's default)" in capsys.readouterr().err
    assert main(argv + ["--spz-axes", "rdf"]) == 0
    assert "data read as RDF (--spz-axes), taken as stored" in capsys.readouterr().err


@pytest.mark.parametrize("name,data,needle", [
    ("cut.spz", None, "cut short"),
    ("junk.spz", b"not an spz file at all", "not an SPZ file"),
    ("gz.spz", gzip.compress(b"NGSP" + struct.pack("<IIBBBx", 3, 10**9, 0, 12, 0)), "announces 1000000000"),
    ("cut.compressed.ply", None, "cut short"),
    ("junk.sog", b"PK\x03\x04 broken", "not a SOG bundle"),
])
def test_cli_corrupt_files_exit_2_with_one_line(tmp_path, capsys, name, data, needle):
    path = tmp_path / name
    if data is None:  # a real file cut in half
        source = DATA / ("biker.spz" if name.endswith(".spz") else "guitar.compressed.ply")
        data = source.read_bytes()[: source.stat().st_size // 2]
    path.write_bytes(data)
    code = main(["render", str(path), "-o", str(tmp_path / "x.exr"), "--width", "8", "--height", "8"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("dofview: error: ") and str(path) in err[0]
    assert needle in err[0] and not (tmp_path / "x.exr").exists()


def test_writer_refuses_what_spz_cannot_hold(tmp_path):
    far = random_scene(n=10)
    far.means[0] = (1e9, 0, 0)
    with pytest.raises(SceneFormatError, match="24-bit"):
        write_spz(far, tmp_path / "far.spz")
    assert not (tmp_path / "far.spz").exists()
    with pytest.raises(DofviewError, match="spz_axes"):
        read_spz(DATA / "biker.spz", spz_axes="luf")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert read_spz(DATA / "biker.spz", progress=None).count == 152_746


def test_spz_lying_sizes_are_refused_before_allocating(tmp_path):
    """A gzip stream that inflates far past what its header announces (a deflate bomb) and a v4
    header whose count needs more than the file can hold: refused with at most a few MB allocated."""
    import tracemalloc

    bomb = tmp_path / "bomb.spz"
    bomb.write_bytes(gzip.compress(struct.pack("<IIIBBBx", 0x5053474E, 3, 10, 0, 12, 0) + bytes(64 << 20), 1))
    v4 = bytearray((DATA / "biker.spz").read_bytes()[:4096])
    v4[8:12] = struct.pack("<I", 2**31 - 1)
    lying = tmp_path / "lying.spz"
    lying.write_bytes(bytes(v4))
    for path, needle in ((bomb, "holds more than its header announces"), (lying, "announces 2147483647")):
        tracemalloc.start()
        try:
            with pytest.raises(SceneFormatError, match=needle):
                read_spz(path)
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        assert peak < 8 << 20, (path.name, peak)


def _webp(path: Path, rgba: np.ndarray) -> None:
    from PIL import Image

    Image.fromarray(np.ascontiguousarray(rgba, np.uint8), "RGBA").save(path, lossless=True, quality=100, exact=True)  # keep RGB under alpha 0


def test_sog_version_1_layout(tmp_path):
    """SOG v1 (no "version": per-channel min…max ranges, the opacity logit beside the colour, one
    scalar SH range) read from a folder this test encodes by that layout; values within half an
    8-bit (16-bit for positions) step."""
    n, side = 1000, 32
    scene = random_scene(n=n, degree=1, seed=9)

    def image(values: np.ndarray) -> np.ndarray:  # (n, ≤4) uint8 → (side, side, 4), alpha 255
        out = np.zeros((side * side, 4), np.uint8)
        out[:, 3] = 255
        out[:n, :values.shape[1]] = values
        return out.reshape(side, side, 4)

    def ranged(v: np.ndarray, bits: int = 8):
        lo, hi = v.min(0), v.max(0)
        return np.round((v - lo) / (hi - lo) * (2**bits - 1)).astype(np.int64), lo, hi

    logged = np.sign(scene.means) * np.log1p(np.abs(scene.means.astype(np.float64)))
    m16, mlo, mhi = ranged(logged, 16)
    q = scene.unit_quats()
    big = np.abs(q).argmax(1)
    q *= np.where(q[np.arange(n), big] < 0, -1.0, 1.0)[:, None]
    others = np.stack([np.delete(row, b) for row, b in zip(q, big)])
    s8, slo, shi = ranged(np.log(scene.scales.astype(np.float64)))
    logit = np.log(scene.opacities / (1.0 - scene.opacities))
    c8, clo, chi = ranged(np.column_stack([scene.sh_dc, logit]))
    rest = scene.sh_rest.astype(np.float64)
    r8 = np.round((rest - rest.min()) / (rest.max() - rest.min()) * 255).astype(np.uint8)  # (n, 3, 3)
    centroids = np.zeros((16, 64 * 3, 4), np.uint8)
    centroids.reshape(-1, 3, 4)[:n, :, :3] = r8  # palette entry i = Gaussian i
    labels = np.column_stack([np.arange(n) & 255, np.arange(n) >> 8])
    files = {"means_l.webp": image(m16 & 255), "means_u.webp": image(m16 >> 8),
             "quats.webp": image(np.column_stack([np.round((others * np.sqrt(2) * 0.5 + 0.5) * 255), 252 + big])),
             "scales.webp": image(s8), "sh0.webp": image(c8), "shN_centroids.webp": centroids,
             "shN_labels.webp": image(labels)}
    for name, rgba in files.items():
        _webp(tmp_path / name, rgba)
    meta = {"means": {"shape": [n, 3], "mins": mlo.tolist(), "maxs": mhi.tolist(),
                      "files": ["means_l.webp", "means_u.webp"]},
            "scales": {"mins": slo.tolist(), "maxs": shi.tolist(), "files": ["scales.webp"]},
            "quats": {"files": ["quats.webp"]},
            "sh0": {"mins": clo.tolist(), "maxs": chi.tolist(), "files": ["sh0.webp"]},
            "shN": {"mins": float(rest.min()), "maxs": float(rest.max()),
                    "files": ["shN_centroids.webp", "shN_labels.webp"]}}
    (tmp_path / "meta.json").write_text(json.dumps(meta))
    back = read_sog(tmp_path)
    assert back.count == n and back.sh_degree == 1

    def half8(lo, hi):
        return 0.5 * (hi - lo) / 255 + 1e-6

    assert np.all(np.abs(np.log(back.scales) - np.log(scene.scales)) <= half8(slo, shi) + 1e-5)
    assert np.all(np.abs(back.sh_dc - scene.sh_dc) <= half8(clo[:3], chi[:3]) + 1e-5)
    assert np.abs(back.sh_rest - scene.sh_rest).max() <= half8(rest.min(), rest.max()) + 1e-5
    assert np.abs(back.means - scene.means).max() <= 1e-3
    assert attribute_errors(back, scene)["rotation"] <= rotation_tol(0.5 * np.sqrt(2) / 255)
    lo_op = 1 / (1 + np.exp(-(logit - half8(clo[3], chi[3]))))
    hi_op = 1 / (1 + np.exp(-(logit + half8(clo[3], chi[3]))))
    assert np.all((back.opacities >= lo_op - 1e-5) & (back.opacities <= hi_op + 1e-5))


def _spz_v4(header_fields: dict, blocks: list[bytes], extensions: bytes = b"") -> bytes:
    """A version-4 .spz assembled from raw attribute blocks (tests of layouts dofview does not write)."""
    import zstandard

    f = {"version": 4, "flags": 0x2 if extensions else 0, "frac": 12, **header_fields}
    packed = [zstandard.ZstdCompressor().compress(b) for b in blocks]
    head = struct.pack("<IIIBBBBI12x", 0x5053474E, f["version"], f["n"], f["degree"], f["frac"], f["flags"],
                       len(blocks), 32 + len(extensions))
    toc = b"".join(struct.pack("<QQ", len(c), len(b)) for c, b in zip(packed, blocks))
    return head + extensions + toc + b"".join(packed)


def test_spz_extension_records_and_degree_4(tmp_path):
    """A coordinate-system record (0xADBE0003) says how the data is stored and is followed;
    unknown records are skipped; a rotated system is refused; SH degree 4 keeps degrees 1–3."""
    scene = random_scene(n=50, degree=3, seed=8)
    data = tmp_path / "s.spz"
    write_spz(scene, data, spz_axes="rdf")
    n, blocks = scene.count, _spz_blocks(data)

    def record(kind: int, payload: bytes) -> bytes:
        return struct.pack("<II", kind, len(payload)) + payload

    unknown = record(0x12340001, b"\x00" * 7)
    as_rdf = tmp_path / "rdf.spz"
    as_rdf.write_bytes(_spz_v4({"n": n, "degree": 3}, blocks, unknown + record(0xADBE0003, struct.pack("<I", 6))))
    lines = []
    a = read_spz(as_rdf, report=lines.append)
    assert "read as RDF (the file's coordinate-system record), taken as stored" in lines[0]
    np.testing.assert_array_equal(a.means, read_spz(data, spz_axes="rdf").means)
    rotated = tmp_path / "rotated.spz"
    rotated.write_bytes(_spz_v4({"n": n, "degree": 3}, blocks, record(0xADBE0003, struct.pack("<I", 10))))
    with pytest.raises(SceneFormatError, match="rotated axes RFD"):
        read_spz(rotated)
    sh4 = np.frombuffer(blocks[5], np.uint8).reshape(n, 15, 3)
    extra = np.full((n, 9, 3), 200, np.uint8)
    four = tmp_path / "four.spz"
    four.write_bytes(_spz_v4({"n": n, "degree": 4}, blocks[:5] + [np.concatenate([sh4, extra], 1).tobytes()]))
    with pytest.warns(DofviewWarning, match="degree 4"):
        b = read_spz(four, spz_axes="rdf")
    assert b.sh_degree == 3
    np.testing.assert_array_equal(b.sh_rest, a.sh_rest)
