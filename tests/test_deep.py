"""Deep output (issue 29): DeepFrame, the deep EXR writer against the OpenEXR library, both
backends' deep images against their flat renders and the CPU twin, the colour space of the
samples, a CG card merged in deep against the card rendered as Gaussians, the camera as OpenEXR
standard attributes against where dofview draws a point, and the command line."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest
from conftest import psnr, random_scene
from inria_folder import SCENES, ring_cameras

from dofview.api import exr_header, render_deep, save_render
from dofview.bench.deep import card, decoded_per_sample, gap_depth, joined
from dofview.camera import Camera, look_at
from dofview.cli import main
from dofview.deep import DeepFrame, DeepSettings
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.io import load_scene
from dofview.io.exr import camera_attributes, read_deep_exr, read_exr, read_exr_header, write_deep_exr, write_exr
from dofview.lens import Lens, LensRequest
from dofview.rendering import deep_gpu
from dofview.rendering.compute import ComputeBackend
from dofview.rendering.quad import QuadBackend
from dofview.rendering.reference import render_reference_deep
from dofview.scene import GaussianScene
from dofview.tonemap import Tonemap

pytestmark = pytest.mark.filterwarnings("ignore:.*trained with antialiasing")  # tap.spz, as it is
PINHOLE = Lens(1.0, 0.0)
CAM = look_at([0.2, -0.1, 0.0], [0.0, 0.0, 5.0], 64, 48, 60)
DATA = ["burger.ply", "two_planes.ply", "biker.spz", "tap.spz", "guitar.compressed.ply"]


def _view(name: str, size=(120, 90)) -> tuple[GaussianScene, Camera]:
    return load_scene(SCENES / name, progress=False), ring_cameras(SCENES / name, size=size)[1]


def _flat_rgba(path) -> tuple[np.ndarray, dict]:
    ch, header = read_exr(path)
    return np.stack([ch[c] for c in "RGBA"], -1), header


def _db(a: np.ndarray, b: np.ndarray) -> float:
    return psnr(a, b, max(1.0, float(b.max())))


def _contributions(image: DeepFrame) -> np.ndarray:
    """(S, 4) what each sample adds to its flattened pixel: its RGBA times the transmittance in front."""
    out = image.rgba.astype(np.float64).copy()
    counts, start = image.counts.ravel(), image.offsets[:-1]
    trans = np.ones(counts.size)
    for k in range(int(counts.max()) if counts.size else 0):
        px = np.nonzero(counts > k)[0]
        out[start[px] + k] *= trans[px, None]
        trans[px] *= 1.0 - image.rgba[start[px] + k, 3]
    return out


# ---- the data type -----------------------------------------------------------------------------------
def test_flatten_merge_and_order_of_hand_made_samples():
    counts = np.array([[2, 0], [1, 1]])
    rgba = [[0.5, 0, 0, 0.5], [0, 0.25, 0, 0.5], [0.1, 0.1, 0.1, 1.0], [0.2, 0.0, 0.0, 0.4]]
    depth = [[1, 1], [2, 2.5], [3, 3], [4, 4]]
    image = DeepFrame(counts, rgba, depth)
    flat = image.flatten()
    np.testing.assert_allclose(flat[0, 0], [0.5, 0.125, 0.0, 0.75])
    np.testing.assert_allclose(flat[0, 1], 0.0)
    np.testing.assert_allclose(flat[1, 0], [0.1, 0.1, 0.1, 1.0], rtol=1e-6)
    # the same samples stored back to front flatten the same: flatten orders by Z
    backwards = DeepFrame(counts, [rgba[1], rgba[0], *rgba[2:]], [depth[1], depth[0], *depth[2:]])
    np.testing.assert_allclose(backwards.flatten(), flat)
    # a sample merged in between: over the first, under the second
    card = DeepFrame(np.array([[1, 0], [0, 0]]), [[0.0, 0.0, 1.0, 1.0]], [[1.5, 1.5]])
    merged = image.merge(card)
    assert merged.counts[0, 0] == 3 and list(merged.pixel(0, 0)[1][:, 0]) == [1.0, 1.5, 2.0]
    np.testing.assert_allclose(merged.flatten()[0, 0], [0.5, 0.0, 0.5, 1.0])
    assert image.sample_stats() == {"mean": 1.0, "p99": pytest.approx(1.97), "max": 2, "empty": 0.25}
    with pytest.raises(ValueError):
        DeepFrame(counts, rgba[:3], depth[:3])


def test_deep_settings_round_trip_and_refusals():
    s = DeepSettings(0.025, 7)
    assert DeepSettings.from_dict(s.to_dict()) == s and DeepSettings.from_dict({}) == DeepSettings()
    assert s.to_args() == ["--deep-tolerance", "0.025", "--deep-cap", "7"]
    for bad in ({"tolerance": 0.0}, {"tolerance": -1.0}, {"tolerance": float("nan")}, {"cap": 0}):
        with pytest.raises(DofviewError):
            DeepSettings(**bad)
    with pytest.raises(DofviewError, match="unknown entry"):
        DeepSettings.from_dict({"tol": 1})


# ---- the writer, read back by the OpenEXR library --------------------------------------------------
def test_deep_exr_written_here_reads_back_in_the_openexr_library(tmp_path):
    rng = np.random.default_rng(3)
    counts = rng.integers(0, 4, (23, 31))
    counts[5] = 0  # an empty row
    total = int(counts.sum())
    channels = {c: rng.random(total).astype(np.float32) for c in ("R", "G", "B", "A", "Z", "ZBack")}
    channels["G"][:] = 0.25  # compresses: those chunks are stored zipped, the random ones raw
    m = np.arange(16, dtype=np.float32).reshape(4, 4)
    header = {"dofview:camera": '{"a": 1}', "dofview:frame": 7, "dofview:exposure": 1.5, "worldToCamera": m,
              "sensorOverallDimensions": np.array([36.0, 24.0], np.float32)}
    path = tmp_path / "d.exr"
    write_deep_exr(path, counts, channels, header)
    back_counts, back, h = read_deep_exr(path)
    assert np.array_equal(back_counts, counts)
    assert all(np.array_equal(back[c], channels[c]) for c in channels)
    assert h["dofview:camera"] == '{"a": 1}' and h["dofview:frame"] == 7 and h["dofview:exposure"] == 1.5
    assert np.array_equal(h["worldToCamera"], m) and np.array_equal(h["sensorOverallDimensions"], [36, 24])
    assert h["maxSamplesPerPixel"] == counts.max() and h["chunkCount"] == 23
    assert read_exr_header(path)["dofview:frame"] == 7
    write_deep_exr(tmp_path / "empty.exr", np.zeros((3, 4), int), {c: np.zeros(0, np.float32) for c in "RGBAZ"})
    assert read_deep_exr(tmp_path / "empty.exr")[0].sum() == 0
    write_exr(tmp_path / "flat.exr", np.zeros((2, 2, 4)))
    with pytest.raises(DofviewError, match="not a deep scanline EXR"):
        DeepFrame.load(tmp_path / "flat.exr")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.exr", "empty.exr", "flat.exr"]  # no temporary files left


def test_a_full_disk_leaves_the_old_deep_file_and_no_temporary(tmp_path, monkeypatch):
    import errno
    import io

    from dofview.io import exr as exr_mod

    path = tmp_path / "d.exr"
    image = DeepFrame(np.ones((2, 3), int), np.full((6, 4), 0.5), np.ones((6, 2)))
    image.save_deep_exr(path)
    before = path.read_bytes()

    class Full(io.BytesIO):
        def write(self, data):
            if self.tell() + len(data) > 300:
                raise OSError(errno.ENOSPC, "No space left on device")
            return super().write(data)

    monkeypatch.setattr(exr_mod, "open", lambda *a, **k: Full(), raising=False)
    with pytest.raises(DofviewError, match="No space left on device.*nothing was written"):
        DeepFrame(np.full((40, 50), 3), np.random.default_rng(0).random((6000, 4)), np.ones((6000, 2))).save_deep_exr(path)
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["d.exr"]


# ---- both backends against their flat renders and the CPU twin ---------------------------------------
@pytest.mark.parametrize("name", DATA)
def test_flattened_deep_exr_is_the_flat_exr(backend, name, tmp_path):
    """The pinhole's deep EXR, flattened, against the flat EXR of the same call (exposure applied
    to both): ≥ 50 dB on every scene of tests/data, on both backends (88–173 dB on the shared
    scenes at 480×360: docs/BENCHMARKS.md, "Deep output")."""
    scene, camera = _view(name)
    renderer = backend(scene)
    try:
        save_render(renderer, camera, PINHOLE, Tonemap(exposure=0.5), RenderSettings(), name, tmp_path / "f.exr",
                    deep=tmp_path / "d.exr")
    finally:
        renderer.release()
    flat, header = _flat_rgba(tmp_path / "f.exr")
    image = DeepFrame.load(tmp_path / "d.exr")
    assert image.samples > 0 and image.counts.max() <= DeepSettings().cap
    assert _db(image.flatten(), flat) >= 50.0
    assert json.loads(image.meta["dofview:deep"]) == DeepSettings().to_dict()
    for key in ("dofview:camera", "dofview:lens", "dofview:render", "worldToNDC", "worldToCamera"):
        assert np.array_equal(image.meta[key], header[key])


def test_per_splat_depth_of_field_deep_flattens_to_its_render(backend):
    scene, camera = _view("two_planes.ply", (96, 72))
    lens, settings = Lens(1.6, 40.0), RenderSettings(dof="splat")
    renderer = backend(scene)
    try:
        flat = renderer.render(camera, lens, settings).rgba
        image = renderer.deep(camera, lens, settings)
    finally:
        renderer.release()
    assert _db(image.flatten(), flat) >= 50.0


@pytest.mark.parametrize("colour_space", ["srgb", "linear"])
def test_deep_matches_the_cpu_twin(backend, colour_space):
    """Sample by sample against rendering.reference.render_reference_deep: the same counts almost
    everywhere (a float32 depth can fall the other side of a tolerance), the same contributions
    where they agree (within 5e-3, as the flat images of float32 and float64 splats differ by up
    to 4e-3 here), and the same flattened image."""
    scene = random_scene(colour_space=colour_space)
    deep = DeepSettings(0.02, 16)
    renderer = backend(scene)
    try:
        gpu = renderer.deep(CAM, PINHOLE, RenderSettings(), deep)
        flat = renderer.render(CAM, PINHOLE).rgba
    finally:
        renderer.release()
    twin = render_reference_deep(scene, CAM, deep=deep)
    same = (gpu.counts == twin.counts).ravel()
    assert same.mean() >= 0.99 and gpu.counts.max() <= 16
    assert _db(gpu.flatten(), twin.flatten()) >= 60.0 and _db(gpu.flatten(), flat) >= 50.0
    in_same = np.repeat(same, gpu.counts.ravel())
    twin_same = np.repeat(same, twin.counts.ravel())
    assert np.abs(_contributions(gpu)[in_same] - _contributions(twin)[twin_same]).max() < 5e-3
    # tidy samples: front to back, each within its tolerance (the cap's last aside), not overlapping
    z, back = gpu.depth[:, 0], gpu.depth[:, 1]
    pix = np.repeat(np.arange(gpu.counts.size), gpu.counts.ravel())
    nxt = pix[1:] == pix[:-1]
    assert np.all(back >= z) and np.all(z[1:][nxt] >= back[:-1][nxt])
    last = np.r_[~nxt, True] & (np.repeat(gpu.counts.ravel(), gpu.counts.ravel()) == 16)
    assert np.all((back <= z * (1 + deep.tolerance) * (1 + 1e-6)) | last)
    assert np.all((gpu.rgba[:, 3] >= 0) & (gpu.rgba[:, 3] <= 1)) and gpu.rgba[:, :3].min() >= -1e-6


def test_a_cap_of_two_keeps_the_image(backend):
    scene = random_scene(seed=2)
    renderer = backend(scene)
    try:
        image = renderer.deep(CAM, deep=DeepSettings(0.001, 2))
        flat = renderer.render(CAM, PINHOLE).rgba
    finally:
        renderer.release()
    assert image.counts.max() == 2 and _db(image.flatten(), flat) >= 50.0


def test_passes_bands_and_slices_give_the_same_samples(backend, monkeypatch):
    """Walks cut into passes (llvmpipe's loop limit, here 7 splats a pass), the image into bands
    (here ≤ 3000 fragments or samples each) and, on the compute backend, the pairs into depth
    slices: the same deep image, bit for bit."""
    scene = random_scene(seed=4)
    whole = backend(scene).deep(CAM)
    monkeypatch.setattr(deep_gpu, "BAND_ITEMS", 3000)
    monkeypatch.setattr(sys.modules[backend.__module__], "walk_take", lambda ctx: 7)
    resumed, counted = [], []
    set_pass, run = deep_gpu.DeepWalk.set_pass, deep_gpu.DeepWalk.run

    def spy_pass(self, program, resume, last):
        resumed.append(resume)
        set_pass(self, program, resume, last)

    def spy_run(self, program, width, height, deep, encoded, walk, bands, prepare=None):
        counted.append(len(bands))
        return run(self, program, width, height, deep, encoded, walk, bands, prepare)

    monkeypatch.setattr(deep_gpu.DeepWalk, "set_pass", spy_pass)
    monkeypatch.setattr(deep_gpu.DeepWalk, "run", spy_run)
    kw = {"max_pairs": 800} if backend is ComputeBackend else {}
    renderer = backend(scene, **kw)
    parts = renderer.deep(CAM)
    assert sum(resumed) > 10 and (counted[0] > 3 if backend is QuadBackend else renderer.pairs > 3 * 800)
    assert np.array_equal(parts.counts, whole.counts)
    assert np.array_equal(parts.rgba, whole.rgba) and np.array_equal(parts.depth, whole.depth)


def test_more_than_65k_splats_in_one_pixel(backend):
    """70 000 very faint splats over one pixel at distinct depths (τ = 0): the walk reaches every
    one, in passes where loops are limited (llvmpipe ends a loop after 65 535 iterations), and the
    cap's last sample takes what the first 9 999 leave: the pixel flattens to its flat value, half
    covered (a walk cut at 65 535 would lose 7 % of it)."""
    rng = np.random.default_rng(5)
    n = 70_000
    cam = Camera(8, 8, 100.0, 100.0, 4.0, 4.0, np.eye(3), np.zeros(3))
    z = rng.uniform(1.0, 3.0, n)
    means = np.stack([(4.5 - cam.cx) / 100 * z, (4.5 - cam.cy) / 100 * z, z], 1)
    scene = GaussianScene(means, np.tile([1.0, 0, 0, 0], (n, 1)), np.full((n, 3), 1e-4), np.full(n, 1e-5),
                          rng.uniform(0, 1, (n, 3)), colour_space="linear")
    settings = RenderSettings(tau=0.0)
    renderer = backend(scene, packed=False)  # (packing keeps 8 bits of opacity)
    try:
        image = renderer.deep(cam, PINHOLE, settings, DeepSettings(1e-9, 10_000))
        flat = renderer.render(cam, PINHOLE, settings).rgba
    finally:
        renderer.release()
    assert image.counts[4, 4] == 10_000 and 0.4 < flat[4, 4, 3] < 0.6
    np.testing.assert_allclose(image.flatten()[4, 4], flat[4, 4], rtol=1e-3)


def test_a_view_of_nothing_has_no_samples(backend):
    renderer = backend(random_scene(200))
    try:
        image = renderer.deep(look_at([0, 0, 0], [0, 0, -5], 32, 24, 60))  # looking away from the cloud
    finally:
        renderer.release()
    assert image.samples == 0 and image.counts.shape == (24, 32) and not image.flatten().any()


# ---- colour space: telescoped samples ----------------------------------------------------------------
def _two_layers(colour_space: str) -> tuple[GaussianScene, GaussianScene]:
    """Semi-transparent blobs around z = 4 in front of a denser cloud around z = 8 (and the front alone)."""
    a, b = random_scene(800, seed=6, colour_space=colour_space), random_scene(800, seed=7, colour_space=colour_space)
    a.means[:, 2] = 4.0 + 0.2 * (a.means[:, 2] - 5.0)
    b.means[:, 2] = 8.0 + 0.2 * (b.means[:, 2] - 5.0)
    a.opacities[:] = np.minimum(a.opacities, 0.6)
    return joined(a, b), a


def test_samples_in_front_of_a_depth_flatten_to_what_lies_in_front():
    """An sRGB scene blends encoded colours; its samples are telescoped through the decode, so
    every prefix flattens to the scene's own image of what lies in front (here: the front layer
    rendered alone), and all of them to the flat image. Each sample decoded on its own (the
    alternative) does neither: it is measured here to fail the same bound."""
    scene, front = _two_layers("srgb")
    cam = look_at([0, 0, 0], [0, 0, 5], 64, 48, 60)
    renderer = QuadBackend(scene)
    image = renderer.deep(cam)
    flat = renderer.render(cam, PINHOLE).rgba
    renderer.release()
    front_flat = QuadBackend(front).render(cam, PINHOLE).rgba
    near = image.depth[:, 1] < 6.0
    pixel = np.repeat(np.arange(image.counts.size), image.counts.ravel())
    prefix = DeepFrame(np.bincount(pixel[near], minlength=image.counts.size).reshape(image.shape), image.rgba[near],
                       image.depth[near])
    assert _db(prefix.flatten(), front_flat) >= 50.0 and _db(image.flatten(), flat) >= 50.0
    assert _db(decoded_per_sample(image).flatten(), flat) < 45.0


@pytest.mark.parametrize("name", ["two_planes.ply", "tap.spz"])
def test_a_card_merged_in_deep_equals_the_card_rendered_with_the_scene(backend, name):
    """A synthetic CG card at a depth between two layers of the scene (bench.deep.gap_depth: the
    box's top and its side; the tap and the wall behind it), rendered deep on its own, merged
    sample by sample (a compositor's DeepMerge) and flattened, against the scene rendered with
    the card's Gaussians: ≥ 35 dB (measured 39.9 and 40.2 dB as trained, in sRGB, whose scenes
    blend the card in their encoded space and a deep merge in linear light; read as linear, 55.2
    and 90.2 dB). The same card merged in front of everything is ≥ 5 dB further off."""
    scene, camera = _view(name)
    renderer = backend(scene)
    image = renderer.deep(camera)
    renderer.release()
    plate = card(camera, gap_depth(image), scene)
    renderer = backend(plate)
    card_image = renderer.deep(camera)
    renderer.release()
    renderer = backend(joined(scene, plate))
    truth = renderer.render(camera, PINHOLE).rgba
    renderer.release()
    merged = _db(image.merge(card_image).flatten(), truth)
    in_front = DeepFrame(card_image.counts, card_image.rgba, np.full_like(card_image.depth, 1e-3))
    assert merged >= 35.0 and _db(image.merge(in_front).flatten(), truth) < merged - 5.0


# ---- the camera a compositor reads ---------------------------------------------------------------------
def test_the_header_matrices_project_a_point_where_dofview_draws_it(tmp_path):
    """One small Gaussian, off the image centre, seen by a turned camera with an off-centre
    principal point and non-square pixels. Its world point times worldToNDC (row vector, divided
    by w), scaled by the image size, lands on the alpha-weighted centre of the drawn blob (pixel
    centres at +½) within 0.02 px, in the flat EXR's header and the deep one's; times
    worldToCamera it has the EXR's depth as z, x > 0 right of the centre and y > 0 above it."""
    base = look_at([0.3, -0.2, -0.5], [0.0, 0.1, 4.0], 96, 72, 55)
    camera = Camera(96, 72, base.fx, base.fx * 1.1, 41.3, 30.7, base.R, base.T)
    point = camera.R.T @ (np.array([(70.2 - camera.cx) / camera.fx * 4, (20.6 - camera.cy) / camera.fy * 4, 4.0])
                          - camera.T)
    scene = GaussianScene(point[None], [[1.0, 0, 0, 0]], [[0.006, 0.006, 0.006]], [0.9], [[1.0, 1.0, 1.0]],
                          colour_space="linear")
    renderer = QuadBackend(scene)
    save_render(renderer, camera, PINHOLE, Tonemap(), RenderSettings(), "one", tmp_path / "f.exr",
                deep=tmp_path / "d.exr")
    renderer.release()
    ch, header = read_exr(tmp_path / "f.exr")
    alpha = ch["A"]
    ys, xs = np.mgrid[0:72, 0:96] + 0.5
    drawn = np.array([(alpha * xs).sum(), (alpha * ys).sum()]) / alpha.sum()
    for h in (header, read_exr_header(tmp_path / "d.exr")):
        row = np.append(point, 1.0) @ h["worldToNDC"].astype(np.float64)
        ndc = row[:2] / row[3]
        assert np.abs(ndc * [96, 72] - drawn).max() < 0.02
        assert 0.0 < row[2] / row[3] < 1.0  # NDC z = 1 − near/z
        cam = np.append(point, 1.0) @ h["worldToCamera"].astype(np.float64)
        peak = np.unravel_index(np.argmax(alpha), alpha.shape)
        assert cam[2] == pytest.approx(ch["Z"][peak], rel=1e-4) and cam[0] > 0 and cam[1] > 0
        assert cam[3] == pytest.approx(1.0)


def test_a_physical_lens_writes_focus_fnumber_and_focal_lengths():
    camera = look_at([0, 0, 0], [0, 0, 1], 160, 90, 60)
    request = LensRequest(fnumber=2.8, focal_mm=50.0, sensor_mm=36.0, units_per_metre=2.0)
    lens = request.lens(camera, 5.0)
    header = exr_header(camera, lens, Tonemap(), RenderSettings(), "srgb", "s", request.to_dict())
    assert header["focus"] == 2.5 and header["aperture"] == 2.8 and header["nominalFocalLength"] == 50.0
    assert header["pinholeFocalLength"] == pytest.approx(camera.fx * 36.0 / 160)
    np.testing.assert_allclose(header["sensorOverallDimensions"], [36.0, 20.25])
    assert "focus" not in exr_header(camera, Lens(5.0, 10.0), Tonemap(), RenderSettings(), "srgb", "s")
    assert camera_attributes(camera, 0.01)["worldToCamera"].dtype == np.float32


def test_render_deep_api():
    scene = random_scene(300)
    image = render_deep(scene, CAM, raster="compute")
    assert image.samples and json.loads(image.meta["dofview:deep"])["cap"] == DeepSettings().cap
    assert render_deep(scene, CAM, Lens(5.0, 10.0)).samples  # the sliced depth of field: tests/test_deep_sliced.py


# ---- the command line -------------------------------------------------------------------------------------
CARDS_ARGS = [str(SCENES.parent.parent / "samples" / "cards.ply"), "--width", "80", "--height", "60"]


def test_render_writes_the_deep_exr_beside_the_flat_one(tmp_path, capsys):
    assert main(["render", *CARDS_ARGS, "--aperture", "0", "--exposure", "1", "-o", str(tmp_path / "f.exr"),
                 "--deep", str(tmp_path / "d.exr"), "--deep-tolerance", "0.02", "--deep-cap", "5"]) == 0
    assert "d.exr" in capsys.readouterr().err
    flat, header = _flat_rgba(tmp_path / "f.exr")
    image = DeepFrame.load(tmp_path / "d.exr")
    assert image.counts.max() <= 5 and _db(image.flatten(), flat) >= 50.0
    assert json.loads(image.meta["dofview:deep"]) == {"tolerance": 0.02, "cap": 5}


@pytest.mark.parametrize("argv,needle", [
    (["--deep", "{tmp}/folder.exr"], "is a folder"),
    (["--deep", "{tmp}/d.png"], "--deep must name an .exr file"),
    (["--deep", "{tmp}/d.exr", "--deep-tolerance", "0"], "--deep-tolerance must be > 0"),
    (["--deep", "{tmp}/d.exr", "--deep-tolerance", "-0.5"], "--deep-tolerance must be > 0"),
    (["--deep", "{tmp}/d.exr", "--deep-cap", "0"], "--deep-cap must be ≥ 1"),
    (["--deep", "{tmp}/f.exr"], "another file than -o"),
    (["--deep", "{tmp}/d.exr", "--lens-samples", "2"], "--lens-samples"),
    (["--deep", "{tmp}/d.exr", "--frames", "2", "--focus", "2:4", "-o", "{tmp}/f_%04d.exr"],
     "--deep of a sequence needs one frame number"),
])
def test_bad_deep_values_are_one_line_errors_and_write_nothing(tmp_path, capsys, argv, needle):
    (tmp_path / "folder.exr").mkdir()
    args = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    lens = [] if "--aperture" in args else ["--aperture", "0"]
    try:
        status = main(["render", *CARDS_ARGS, *lens, "-o", str(tmp_path / "f.exr"), *args])
    except SystemExit as e:  # argparse's own refusals
        status = e.code
    assert status == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1 and "Traceback" not in err
    assert [p.name for p in tmp_path.iterdir()] == ["folder.exr"]


def test_deep_sequences_resume_and_range(tmp_path, capsys):
    """A 3-frame focus pull with --dof splat: --range renders its frames' flat and deep EXRs;
    --resume renders only the missing frame, again the ones whose deep file is gone, and all of
    them when the deep settings change."""
    out = ["-o", str(tmp_path / "f_%04d.exr"), "--deep", str(tmp_path / "d_%04d.exr")]
    base = ["render", *CARDS_ARGS, "--dof", "splat", "--aperture", "30", "--frames", "3", "--focus", "2:8", *out]
    assert main([*base, "--range", "0:1"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d_0000.exr", "d_0001.exr", "f_0000.exr", "f_0001.exr"]
    assert main([*base, "--resume"]) == 0
    assert "1 rendered" in capsys.readouterr().err
    for i in range(3):
        flat, header = _flat_rgba(tmp_path / f"f_{i:04d}.exr")
        image = DeepFrame.load(tmp_path / f"d_{i:04d}.exr")
        assert image.meta["dofview:frame"] == i and image.meta["dofview:lens"] == header["dofview:lens"]
        assert _db(image.flatten(), flat) >= 50.0
    (tmp_path / "d_0001.exr").unlink()
    assert main([*base, "--resume"]) == 0
    assert "1 rendered, 2 already there" in capsys.readouterr().err
    assert main([*base, "--resume", "--deep-tolerance", "0.05"]) == 0
    assert "3 rendered (3 of them again: their recorded deep (3)" in capsys.readouterr().err
    assert json.loads(read_exr_header(tmp_path / "d_0002.exr")["dofview:deep"])["tolerance"] == 0.05
