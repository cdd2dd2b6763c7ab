"""The compute tile rasteriser (rendering/compute.py) against the quad backend, the CPU reference
and its own stages: samples and a real scene, tile-boundary cases (a splat on a tile corner, one
larger than the screen, > 65k splats in one tile), depth slices, refusals, the CLI."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import psnr, random_scene
from inria_folder import SCENES

from dofview.bench import synth
from dofview.camera import Camera, framing_camera, look_at
from dofview.cli import main
from dofview.errors import BackendUnavailable, DofviewError
from dofview.frame import RenderSettings
from dofview.io import load_scene
from dofview.io.cameras import load_cameras_json
from dofview.io.exr import read_exr
from dofview.lens import Lens
from dofview.rendering import AUTO_ORDER, BACKENDS, get_backend
from dofview.rendering import compute as compute_mod
from dofview.rendering.compute import PER_GAUSSIAN_BYTES, ComputeBackend
from dofview.rendering.gpu_sort import require_compute
from dofview.rendering.quad import QuadBackend
from dofview.rendering.reference import project, render_reference
from dofview.rendering.slices import SLICE_RULE
from dofview.scene import GaussianScene

SAMPLES = Path(__file__).resolve().parent.parent / "samples"
CAM = look_at([0.2, -0.1, 0.0], [0.0, 0.0, 5.0], 96, 72, 60)


def assert_same_image(a, b, min_db=45.0):
    """Linear RGBA PSNR (peak: the brightest value, at least 1) and depth where both are covered."""
    peak = max(float(b.rgba.max()), 1.0)
    assert psnr(a.rgba, b.rgba, peak) >= min_db
    both = (a.alpha > 0.5) & (b.alpha > 0.5)
    if both.any():
        assert np.max(np.abs(a.depth[both] - b.depth[both]) / b.depth[both]) <= 1e-3


@pytest.mark.parametrize("name", ["cards", "lamp"])
@pytest.mark.parametrize("aperture", [0.0, 100.0])
def test_compute_matches_quad_on_samples(name, aperture):
    scene = load_scene(SAMPLES / f"{name}.ply", progress=False)
    cam = load_cameras_json(SAMPLES / f"{name}_cameras.json")[2].resized(160, 120)
    lens = Lens({"cards": 4.0, "lamp": synth.LAMP_DEPTH}[name], aperture)
    assert_same_image(ComputeBackend(scene).render(cam, lens), QuadBackend(scene).render(cam, lens))


@pytest.mark.parametrize("file", ["two_planes.ply", "burger.ply"])
def test_compute_matches_quad_on_the_data_scenes(file):
    scene = load_scene(SCENES / file, progress=False)
    cam = framing_camera(scene, 160, 120)
    focus = float(np.linalg.norm(cam.centre - scene.means.mean(0)))
    for aperture in (0.0, 60.0):
        lens = Lens(focus, aperture)
        assert_same_image(ComputeBackend(scene).render(cam, lens), QuadBackend(scene).render(cam, lens))


@pytest.mark.parametrize("kernel", ["gaussian", "disk"])
def test_preprocess_stage_matches_reference_projection(kernel):
    """The per-Gaussian records read back (centre, blurred covariance with the CoC, o′, depth, kernel
    shape) against rendering.reference.project, in float64, for every Gaussian the kernel kept."""
    scene = random_scene(degree=1, seed=12)
    settings = RenderSettings(tau=1 / 255, kernel=kernel, dof="splat")
    lens = Lens(4.0, 70.0)
    r = ComputeBackend(scene, packed=False)
    r.draw(CAM, lens, settings)
    rec = np.frombuffer(r._splats.read(), np.float32).reshape(-1, 12).astype(np.float64)
    rects = np.frombuffer(r._rects.read(), np.uint32).reshape(-1, 2)
    drawn = np.nonzero((rects[:, 1] & 0xFFFF) > (rects[:, 0] & 0xFFFF))[0]
    pr = project(scene, CAM, lens, settings)
    assert set(drawn) <= set(pr["idx"]) and len(drawn) > 0.5 * len(pr["idx"])
    at = {g: i for i, g in enumerate(pr["idx"])}
    sel = np.array([at[g] for g in drawn])
    h = CAM.height
    np.testing.assert_allclose(rec[drawn, 0], pr["mean2d"][sel, 0], atol=1e-3)
    np.testing.assert_allclose(h - rec[drawn, 1], pr["mean2d"][sel, 1], atol=1e-3)
    ax2 = np.stack([-rec[drawn, 3], rec[drawn, 2]], 1) * rec[drawn, 4:5]  # splat_record.glsl: splat_axis2
    ax1, ax2 = rec[drawn, 2:4] * [1, -1], ax2 * [1, -1]  # back to y down
    conic = ax1[:, :, None] * ax1[:, None, :] + ax2[:, :, None] * ax2[:, None, :]
    cov = np.linalg.inv(conic)
    ref = pr["cov"][sel]
    np.testing.assert_allclose(cov[:, 0, 0], ref[:, 0], rtol=1e-3)
    np.testing.assert_allclose(cov[:, 1, 1], ref[:, 2], rtol=1e-3)
    assert np.all(np.abs(cov[:, 0, 1] - ref[:, 1]) <= 1e-3 * np.sqrt(ref[:, 0] * ref[:, 2]))
    np.testing.assert_allclose(rec[drawn, 6], pr["opacity"][sel], rtol=1e-4)
    np.testing.assert_allclose(rec[drawn, 7], pr["depth"][sel], rtol=1e-6)
    np.testing.assert_allclose(rec[drawn, 5], pr["shape"][sel], rtol=1e-5)
    if kernel == "disk":
        assert (rec[drawn, 5] < 1).mean() > 0.5  # most splats at A = 70 are spread over a disk
    else:
        assert np.all(rec[drawn, 5] == 1)


def test_draw_count_and_memory():
    scene = random_scene(seed=4)
    c, q = ComputeBackend(scene), QuadBackend(scene)
    splat = RenderSettings(dof="splat")
    for lens in (Lens(4.5, 0.0), Lens(4.5, 300.0)):
        c.draw(CAM, lens, splat, count=True)
        q.draw(CAM, lens, splat, count=True)
        assert c.stats.drawn == q.stats.drawn > 0
    # sliced: each layer counted with the lens it is drawn with (the huge-CoC layers' splats, spread
    # by the lens, may fall below tau): the compute backend per prepared span, the quads per range
    lens = Lens(4.5, 300.0)
    c.slice_rule = q.slice_rule = replace(SLICE_RULE, huge=0.25)  # (the default has no splat beyond the frame here)
    c.draw(CAM, lens, count=True)
    q.draw(CAM, lens, count=True)
    assert any(layer.lensed for layer in q._sliced.layers)
    assert c.stats.drawn == q.stats.drawn > 0
    assert c.gpu_bytes >= q.gpu_bytes - 4 * scene.count + PER_GAUSSIAN_BYTES * scene.count + 16 * c.pairs


def _one(mean, scale, opacity=0.8, colour=(1.0, 0.5, 0.2)) -> GaussianScene:
    return GaussianScene(means=[mean], quats=[[1, 0, 0, 0]], scales=[scale], opacities=[opacity], sh_dc=[colour],
                         colour_space="linear")


def _pixel_camera(width: int = 64, height: int = 48) -> Camera:
    """Identity camera with f = 100 px: a point (x, y, 1) lands on pixel (100 x + cx, 100 y + cy)."""
    return Camera(width, height, 100.0, 100.0, width / 2, height / 2, np.eye(3), np.zeros(3))


@pytest.mark.parametrize("aperture", [0.0, 40.0])
def test_splat_on_a_tile_corner_has_no_seam(aperture):
    """A splat centred on the corner shared by four tiles: the reference's image, and point-symmetric
    about the corner (a tile that dropped or cut it would break the symmetry)."""
    cam = _pixel_camera()
    t = ComputeBackend(_one([0, 0, 1.0], [0.01] * 3)).tile
    x, y = 2 * t, 2 * t  # a tile corner, in pixels (y down)
    scene = _one([(x - cam.cx) / 100.0, (y - cam.cy) / 100.0, 1.0], [0.03, 0.02, 0.01], opacity=0.99)
    r = ComputeBackend(scene, packed=False)
    lens, settings = Lens(2.0, aperture), RenderSettings(tau=0.0, dof="splat")
    frame = r.render(cam, lens, settings)
    assert r.pairs >= 4
    assert_same_image(frame, render_reference(scene, cam, lens, settings), min_db=60.0)
    block = frame.alpha[y - t:y + t, x - t:x + t]
    assert min(q.max() for q in (block[:t, :t], block[:t, t:], block[t:, :t], block[t:, t:])) > 0.05  # all four tiles
    np.testing.assert_allclose(block, block[::-1, ::-1], atol=1e-5)


def test_splat_larger_than_the_screen():
    cam = _pixel_camera()
    scene = _one([0.05, -0.02, 1.0], [3.0, 2.0, 0.1], opacity=0.6)
    lens = Lens(1.0, 0.0)
    c = ComputeBackend(scene, packed=False)
    frame = c.render(cam, lens)
    tiles = -(-cam.width // c.tile) * -(-cam.height // c.tile)
    assert c.pairs == tiles  # clamped to the screen's tiles
    assert frame.alpha.min() > 0.5
    assert_same_image(frame, QuadBackend(scene, packed=False).render(cam, lens), min_db=60.0)


def test_loop_limit_passes_give_the_same_image(monkeypatch):
    """Where the GL limits loop iterations (llvmpipe), duplication and blending run in passes; with
    the limit cut to 40 iterations a full-screen splat and a 1500-splat scene take many of them."""
    scene = random_scene(seed=3)
    scene.scales[0] = [3.0, 3.0, 0.1]  # covers every tile
    lens = Lens(4.0, 40.0)
    whole = ComputeBackend(scene).render(CAM, lens)
    monkeypatch.setattr(compute_mod, "LLVMPIPE_RUN", 40)
    limited = ComputeBackend(scene)
    if limited.loop_limit is None:
        pytest.skip("this GL has no loop limit, so there are no passes to test")
    assert_same_image(limited.render(CAM, lens), whole, min_db=80.0)


def test_more_than_65k_splats_in_one_tile():
    """70 000 tiny splats inside one tile at distinct depths: no counter overflows, the tile
    blends them all (front to back, with early termination) as the quad path does."""
    rng = np.random.default_rng(5)
    n = 70_000
    cam = _pixel_camera()
    px = rng.uniform(2, 6, (n, 2))  # pixels 2…6: inside the first tile whatever its size
    z = rng.uniform(1.0, 3.0, n)
    means = np.stack([(px[:, 0] - cam.cx) / 100 * z, (px[:, 1] - cam.cy) / 100 * z, z], 1)
    scene = GaussianScene(means=means, quats=np.tile([1.0, 0, 0, 0], (n, 1)), scales=np.full((n, 3), 1e-4),
                          opacities=rng.uniform(0.005, 0.02, n), sh_dc=rng.uniform(0, 1, (n, 3)),
                          colour_space="linear")
    lens = Lens(2.0, 0.0)
    c = ComputeBackend(scene)
    c.draw(cam, lens, count=True)
    assert c.stats.drawn == n and c.pairs >= n
    ranges = np.frombuffer(c._ranges.read(), np.uint32).reshape(-1, 2)
    assert (ranges[:, 1] - ranges[:, 0]).max() > 65_536
    assert_same_image(c.read(), QuadBackend(scene).render(cam, lens))


@pytest.mark.parametrize("dof", ["splat", "sliced"])
def test_depth_slices_give_the_same_image(dof):
    """A frame whose pairs exceed max_pairs is drawn in depth slices, continuing the blend (in the
    sliced mode each of its layers binned on its own, where one binning holds them all)."""
    scene = random_scene(seed=8)
    lens, settings = Lens(4.0, 60.0), RenderSettings(dof=dof)
    whole = ComputeBackend(scene).render(CAM, lens, settings)
    parts = ComputeBackend(scene, max_pairs=1000)
    frame = parts.render(CAM, lens, settings)
    assert parts.pairs > 3000
    if dof == "splat":
        assert parts.slices > 3
    assert_same_image(frame, whole, min_db=80.0)


def test_a_window_leaves_the_tiles_without_its_splats_as_they_were():
    """A range of the order (a layer of the sliced mode) writes only the tiles that hold some of
    its splats: every other tile of the image keeps what it held, even one with splats of other
    ranks (a room's layer has splats in a quarter to a third of the image's tiles,
    docs/BENCHMARKS.md "Cost in rooms"), and the tiles it writes are as drawn into a cleared
    target."""
    cam = _pixel_camera()
    near = [(12 - cam.cx) / 100.0, (12 - cam.cy) / 100.0, 1.0]  # pixel (12, 12), nearest first
    far = [2.0 * (50 - cam.cx) / 100.0, 2.0 * (36 - cam.cy) / 100.0, 2.0]  # pixel (50, 36)
    scene = GaussianScene(means=[near, far], quats=[[1, 0, 0, 0]] * 2, scales=[[0.01] * 3, [0.02] * 3],
                          opacities=[0.9, 0.9], sh_dc=[(1.0, 0.5, 0.2)] * 2, colour_space="linear")
    r = ComputeBackend(scene, packed=False)
    try:
        r.sort(cam)
        r.prepare_splats(cam, Lens(1.0, 0.0), RenderSettings(dof="splat"))
        images = []
        for marker in (0.0, 0.25):
            textures = [r.ctx.texture((cam.width, cam.height), 4, dtype="f4") for _ in range(2)]
            target = r.ctx.framebuffer(color_attachments=textures)
            target.clear(marker, marker, marker, marker)
            r.splat_range(0, 1, target)  # the near splat alone
            images.append([np.frombuffer(t.read(), np.float32).reshape(cam.height, cam.width, 4)[::-1]
                           for t in textures])
            target.release()
            for t in textures:
                t.release()
    finally:
        r.release()
    (colour, depth), (kept, kept_depth) = images
    t = r.tile
    mine = np.zeros((cam.height, cam.width), bool)  # the tiles the near splat's pixels lie in
    ys, xs = np.nonzero(colour[..., 3] > 0)
    assert len(ys) and colour[12, 12, 3] > 0.5 and colour[36, 50, 3] == 0.0
    for y, x in zip(ys // t, xs // t):
        mine[y * t:(y + 1) * t, x * t:(x + 1) * t] = True
    assert not mine[36, 50] and mine.mean() < 0.25
    assert np.all(kept[~mine] == 0.25) and np.all(kept_depth[~mine] == 0.25)  # as they were
    np.testing.assert_array_equal(kept[mine], colour[mine])  # written whole, as into a cleared target
    np.testing.assert_array_equal(kept_depth[mine], depth[mine])


def _listed(r: ComputeBackend) -> tuple[np.ndarray, np.ndarray]:
    """The last window's indirect dispatch (x, y, z, tiles listed) and its list of (tile x, tile y,
    first pair, end), in list order."""
    command = np.frombuffer(r._command.read(), np.uint32)
    if not command[3]:  # (GL maps no zero-sized range)
        return command, np.zeros((0, 4), np.uint32)
    return command, np.frombuffer(r._listed.read(size=16 * int(command[3])), np.uint32).reshape(-1, 4)


def test_a_window_lists_exactly_the_tiles_holding_its_ranks():
    """tiles_window.comp lists, for the blend's indirect dispatch, every tile of a window whose pairs
    hold a rank of the range, with that part of the tile's pairs, and no other tile: checked against
    the binned pairs read back and searched in numpy, for ranges of the order and a pixel window."""
    scene = random_scene(seed=8)
    r = ComputeBackend(scene, packed=False)
    try:
        r.sort(CAM)
        r.prepare_splats(CAM, Lens(4.0, 60.0), RenderSettings(dof="splat"))
        target = r.ctx.framebuffer(color_attachments=[r.ctx.texture((CAM.width, CAM.height), 4, dtype="f4")
                                                      for _ in range(2)])
        n, t = scene.count, r.tile
        tx, ty = -(-CAM.width // t), -(-CAM.height // t)
        counts = []
        for first, end, box in ((0, n, None), (n // 3, n // 2, None), (n // 3, n // 2, (20, 10, 60, 50)),
                                (n // 2, n // 2, None)):
            target.clear(0.0, 0.0, 0.0, 0.0)
            r.splat_range(first, end, target, box)
            ranges = np.frombuffer(r._ranges.read(), np.uint32).reshape(ty, tx, 2)
            vals = np.frombuffer(r._vals.read(size=4 * r.pairs), np.uint32)
            x0, y0, x1, y1 = box or (0, 0, CAM.width, CAM.height)
            want = set()
            for y in range(min(CAM.height - y1, CAM.height) // t, -(-(CAM.height - y0) // t)):  # GL rows of tiles
                for x in range(x0 // t, -(-x1 // t)):
                    lo, hi = ranges[y, x]
                    a, b = lo + np.searchsorted(vals[lo:hi], [first, end])
                    if b > a:
                        want.add((x, y, int(a), int(b)))
            command, listed = _listed(r)
            assert {tuple(int(v) for v in e) for e in listed} == want and len(listed) == len(want)
            assert tuple(command) == (min(len(want), 65535), -(-len(want) // 65535), 1, len(want))
            counts.append(len(want))
        # every tile holds some of the whole order; a part of it holds fewer, in a window fewer still
        assert counts[0] == tx * ty > counts[1] > counts[2] > counts[3] == 0
        target.release()
    finally:
        r.release()


@pytest.mark.parametrize("max_pairs", [None, 300])
def test_a_prepared_span_draws_its_ranges_as_the_whole_order_does(max_pairs):
    """prepare_splats with a span projects, counts and bins only the Gaussians of that part of the
    order (the sliced mode's huge-CoC layers, drawn blurred, are a few of a scene): a range within
    it is blended bit for bit as after preparing the whole order, in one pass and in depth slices
    (max_pairs 300), with only the span's pairs made and its Gaussians counted; a range beyond the
    span is refused."""
    scene = random_scene(seed=8)
    r = ComputeBackend(scene, packed=False, max_pairs=max_pairs)
    target = r.ctx.framebuffer(color_attachments=[r.ctx.texture((CAM.width, CAM.height), 4, dtype="f4")
                                                  for _ in range(2)])
    n = scene.count
    lens, settings = Lens(4.0, 60.0), RenderSettings(dof="splat")

    def blend(first, end, span):
        r.prepare_splats(CAM, lens, settings, span=span)
        target.clear(0.0, 0.0, 0.0, 0.0)
        r.splat_range(first, end, target, (10, 5, 80, 60))
        return [np.frombuffer(t.read(), np.float32) for t in target.color_attachments], r.pairs

    try:
        r.sort(CAM)
        whole = {}
        for first, end in ((0, n // 4), (n // 3, n // 2), (n // 2, n)):
            whole[first, end] = blend(first, end, None)
        all_pairs = r.pairs
        for (first, end), (want, _) in whole.items():
            got, pairs = blend(first, end, (first, end))
            assert pairs < all_pairs
            for a, b in zip(got, want):
                np.testing.assert_array_equal(a, b)
            assert np.abs(got[0]).max() > 0  # the range drew something in the box
        # a range within a wider span: the same again
        got, _ = blend(n // 3, n // 2, (n // 4, n))
        for a, b in zip(got, whole[n // 3, n // 2][0]):
            np.testing.assert_array_equal(a, b)
        # counted: the span's Gaussians the projection keeps, as the quads count the range drawn
        q = QuadBackend(scene, packed=False)
        try:
            q.sort(CAM)
            for backend in (r, q):
                backend._counter.write(np.zeros(1, np.uint32).tobytes())
                backend.prepare_splats(CAM, lens, settings, count=True, span=(n // 3, n // 2))
                target.clear(0.0, 0.0, 0.0, 0.0)
                backend.splat_range(n // 3, n // 2, target)
            counted = [int(np.frombuffer(b._counter.read(), np.uint32)[0]) for b in (r, q)]
            assert counted[0] == counted[1] > 0
        finally:
            q.release()
        r.prepare_splats(CAM, lens, settings, span=(n // 3, n // 2))
        with pytest.raises(ValueError, match="outside the prepared span"):
            r.splat_range(n // 4, n // 2, target)
        with pytest.raises(ValueError, match="not within the order"):
            r.prepare_splats(CAM, lens, settings, span=(n // 2, n + 1))
    finally:
        target.release()
        r.release()


def test_more_listed_tiles_than_one_dispatch_row():
    """A window of more tiles holding pairs than one dimension of a dispatch takes (65 535): the list
    is spread over a 2D grid, and the image is the quad backend's (1-pixel tiles, 300 × 240)."""
    cam = _pixel_camera(300, 240)
    scene = _one([0.05, -0.02, 1.0], [3.0, 2.0, 0.1], opacity=0.6)
    lens = Lens(1.0, 0.0)
    c = ComputeBackend(scene, packed=False, tile=1, pix=1)
    try:
        frame = c.render(cam, lens)
        command, listed = _listed(c)
    finally:
        c.release()
    assert command[3] == cam.width * cam.height > 65535 and tuple(command[:3]) == (65535, 2, 1)
    assert len({(int(e[0]), int(e[1])) for e in listed}) == cam.width * cam.height
    assert frame.alpha.min() > 0.4  # every pixel blended, those on the last row of the grid too
    assert_same_image(frame, QuadBackend(scene, packed=False).render(cam, lens), min_db=60.0)


def test_refusals_are_clear_errors(monkeypatch):
    scene = _one([0, 0, 1.0], [3.0, 3.0, 0.1])
    with pytest.raises(DofviewError, match="covers more than 10 tiles"):
        ComputeBackend(scene, max_pairs=10).render(_pixel_camera(), Lens(1.0, 0.0))
    monkeypatch.setattr(compute_mod, "max_buffer_bytes", lambda ctx: 1000)
    with pytest.raises(DofviewError, match="splat buffer"):
        ComputeBackend(random_scene(n=100))


def test_gl_without_compute_shaders_is_unavailable_and_auto_falls_back(monkeypatch):
    class OldGL:
        version_code = 410

    with pytest.raises(BackendUnavailable, match="OpenGL 4.3"):
        require_compute(OldGL())

    def unavailable(ctx):
        raise BackendUnavailable("no compute shaders")

    monkeypatch.setattr(compute_mod, "require_compute", unavailable)
    monkeypatch.setattr("dofview.rendering.AUTO_ORDER", ("compute", "quad"))
    scene = random_scene(n=50)
    with pytest.raises(BackendUnavailable):
        get_backend("compute", scene)
    assert get_backend("auto", scene).name == "quad"
    assert AUTO_ORDER[0] == "quad"  # the order measured here (docs/BENCHMARKS.md "Compute backend")


def test_backends_probe_the_gl_before_uploading_the_scene():
    """Each backend's require() runs before anything is uploaded: on an OpenGL 4.1 context that can
    do nothing else (no buffer() to upload with), every backend and "auto" refuse with the reason."""

    class OldGL:
        version_code = 410
        info: dict = {}

    scene = random_scene(n=50)
    for name in BACKENDS:
        with pytest.raises(BackendUnavailable, match=f"the {name} backend needs OpenGL 4.3"):
            get_backend(name, scene, ctx=OldGL())
    with pytest.raises(BackendUnavailable, match="no renderer backend runs here"):
        get_backend("auto", scene, ctx=OldGL())


def test_render_cli_with_compute(tmp_path):
    common = [str(SAMPLES / "cards.ply"), "--cameras", str(SAMPLES / "cards_cameras.json"), "--view", "1",
              "--width", "160", "--height", "120", "--focus", "4", "--aperture", "60"]
    out = {}
    for raster in ("quad", "compute"):
        exr = tmp_path / f"{raster}.exr"
        assert main(["render", *common, "--raster", raster, "-o", str(exr), "--png", str(tmp_path / f"{raster}.png")]) == 0
        out[raster] = read_exr(exr)[0]
    rgb = {k: np.stack([v[c] for c in "RGBA"], -1) for k, v in out.items()}
    assert psnr(rgb["compute"], rgb["quad"], 1.0) >= 45.0
    covered = rgb["quad"][..., 3] > 0.5
    np.testing.assert_allclose(out["compute"]["Z"][covered], out["quad"]["Z"][covered], rtol=1e-3)


@pytest.mark.parametrize("command", ["render", "view", "bench"])
def test_raster_option_on_every_command(command, capsys):
    with pytest.raises(SystemExit) as e:
        main([command, "--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert "--raster {auto,quad,compute}" in " ".join(out.split())


@pytest.mark.parametrize("blur", [0.0, 646.0])
def test_faint_coverage_keeps_its_precision(blur):
    """A Gaussian blurred until it covers the frame at α ≈ 1.6e-4: the tile blend accumulates the
    coverage as Σ αT, as the quad backend's blend keeps it, so alpha and depth match the float64
    reference to float32's relative precision (1 − Π(1 − α) kept it to 3e-8 absolute: 2e-4 of
    this coverage, and depths off by up to 0.5 % where random frames had less on them)."""
    scene = GaussianScene(means=[[0.1, 0.05, 3.0]], quats=[[0.3, -0.5, 0.7, 0.2]], scales=[[0.2, 0.1, 1e-6]],
                          opacities=[0.9], sh_dc=[[0.5, 0.2, 0.1]])
    cam, lens = look_at([0, 0, 0], [0, 0, 5], 99, 50, 60), Lens(0.47, blur)
    settings = RenderSettings(dof="splat", tau=0.0)
    ref = render_reference(scene, cam, lens, settings)
    frame = get_backend("compute", scene, packed=False).render(cam, lens, settings)
    covered = ref.alpha > 0
    if blur:
        assert covered.mean() > 0.5 and ref.alpha.max() < 2e-4
    np.testing.assert_allclose(frame.alpha[covered], ref.alpha[covered], rtol=2e-5)
    np.testing.assert_allclose(frame.depth[covered], ref.depth[covered], rtol=1e-5)
