"""Sliced depth of field on the GPU (rendering/sliced.py, the default ``--dof sliced``): both
backends against the CPU reference of the mode, the pinhole at A = 0, a slanted floor, a
frame-filling near wall and the bladed aperture against the thin lens, refinement's lens cells,
the settings' round trip and the CLI path."""

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_matches_sliced_reference

from dofview.bench.metrics import psnr
from dofview.bench.primitives import Parts, add_panel
from dofview.bench.sliced_study import ANCHOR
from dofview.bench.synth import receding_floor
from dofview.bench.variants import make_references
from dofview.camera import look_at
from dofview.cli import main
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.io import load_scene
from dofview.io.exr import read_exr
from dofview.lens import Lens, aperture_for_blur
from dofview.rendering import get_backend
from dofview.rendering.depth_order import camera_depths
from dofview.rendering import layer_plan, slices
from dofview.rendering.progressive import lens_cells, render_lens_samples
from dofview.rendering.reference import render_reference_sliced
from dofview.rendering.slices import SLICE_RULE
from dofview.scene import GaussianScene
from dofview.tonemap import Tonemap, encode
from dofview.tonemap.display import display

ROOT = Path(__file__).resolve().parents[1]
CARDS = ROOT / "samples" / "cards.ply"
TWO_PLANES = ROOT / "tests" / "data" / "two_planes.ply"
SLICED = RenderSettings(dof="sliced")
MIN_PSNR = 40.0  # GL float32 against the float64 reference; measured 90 dB on two_planes, 51 on cards (depth ties)


def _view(scene, blur: float, width: int = 160, height: int = 120):
    """A camera looking at ``scene`` from its bounding box's -z side, focused at the median depth,
    with the largest blur between the 5th and 95th depth percentiles ``blur`` px."""
    lo, hi = np.percentile(scene.means, [2, 98], axis=0)
    centre = 0.5 * (lo + hi)
    eye = centre - np.array([0.0, 0.0, 1.6 * float(np.max(hi - lo))])
    cam = look_at(tuple(eye), tuple(centre), width, height, 50.0)
    z = camera_depths(scene.means, cam)
    z = z[z > 0.01]
    focus = float(np.median(z))
    return cam, Lens(focus, aperture_for_blur(blur, focus, float(np.percentile(z, 5)), float(np.percentile(z, 95))))


@pytest.mark.parametrize("blades", [0, 6])
def test_the_gathers_interior_loop_changes_no_bit(blades, monkeypatch):
    """slice_gather.frag leaves out the edge tests for pixels whose every tap lies inside the level
    (u_tap_reach from its edges): the frame is the one with every pixel gathered through the edge
    tests (u_tap_reach beyond the level), bit for bit, on two planes that fill the frame, whose
    layers reach the level's edges and repeat them there (no guard band: those edges are the
    frame's). With the interior loop everywhere (u_tap_reach below 0) the frame differs: its edges
    need the tests."""
    from dofview.rendering import sliced

    scene = load_scene(TWO_PLANES, progress=False)
    cam, lens = _view(scene, 16.0)
    original = sliced.SlicedDof._write_taps
    frames = {}
    for name, reach in (("default", None), ("edge tests", 1 << 20), ("interior", -(1 << 20))):
        def write_taps(self, cell, radius, reach=reach):
            out = original(self, cell, radius)
            if reach is not None:
                self._gather[0]["u_tap_reach"].value = reach
            return out

        monkeypatch.setattr(sliced.SlicedDof, "_write_taps", write_taps)
        r = get_backend("quad", scene)
        # no guard band: the levels' edges are the frame's (the sprites' additive blend follows the GPU's order)
        r.slice_rule = replace(SLICE_RULE, sprites=0.0, guard=0.0)
        try:
            frames[name] = r.render(cam, lens, RenderSettings(blades=blades))
        finally:
            r.release()
    np.testing.assert_array_equal(frames["default"].rgba, frames["edge tests"].rgba)
    np.testing.assert_array_equal(frames["default"].depth, frames["edge tests"].depth)
    assert np.abs(frames["interior"].rgba - frames["default"].rgba).max() > 0.01


@pytest.mark.parametrize("backend", ["quad", "compute"])
@pytest.mark.parametrize("path", [CARDS, TWO_PLANES], ids=["cards", "two_planes"])
def test_sliced_matches_the_cpu_reference(backend, path):
    scene = load_scene(path, progress=False)
    cam, lens = _view(scene, 16.0)
    r = get_backend(backend, scene)
    try:
        gl = r.render(cam, lens, SLICED)
        layers = r.sliced_layers
    finally:
        r.release()
    ref = render_reference_sliced(scene, cam, lens, SLICED)
    assert len(layers) >= 8 and {l.scale for l in layers} >= {1, 2, 4}  # full and reduced resolution
    assert ref.alpha.mean() > 0.1
    assert psnr(gl.rgba, ref.rgba) >= MIN_PSNR
    both = (gl.alpha > 0.5) & (ref.alpha > 0.5) & (ref.depth > 0)
    close = np.abs(gl.depth[both] - ref.depth[both]) <= 1e-3 * ref.depth[both]
    assert close.mean() > 0.99  # the rest: pixels at a splat's 3σ cut, where float32 may decide otherwise


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_huge_coc_layers_drawn_per_splat_match_the_cpu_reference(backend):
    """Splats blurred beyond the frame (SliceRule.huge: 160 px at 160 px wide) are drawn by the
    per-splat method as a front and a back layer: two_planes's floaters in front."""
    scene = load_scene(TWO_PLANES, progress=False)
    cam, lens = _view(scene, 16.0)
    r = get_backend(backend, scene)
    try:
        gl = r.render(cam, lens, SLICED)
        front = r.sliced_layers[0]
        assert front.lensed and front.end > front.first  # the floaters in front
        assert not any(l.lensed for l in r.sliced_layers[1:-1])
    finally:
        r.release()
    ref = render_reference_sliced(scene, cam, lens, SLICED)
    assert psnr(gl.rgba, ref.rgba) >= MIN_PSNR


def _floaters_and_backdrop() -> GaussianScene:
    """40 floaters at the lens and a far backdrop of 40, both blurred beyond the frame by
    Lens(2, 400) at 64 × 48 (front and back layers drawn per splat), and one Gaussian between them
    56° off axis, beyond the 30° frame's reach."""
    rng = np.random.default_rng(1)
    front = np.c_[rng.uniform(-0.1, 0.1, (40, 2)), rng.uniform(0.15, 0.3, 40)]
    back = np.c_[rng.uniform(-40, 40, (40, 2)), rng.uniform(60, 100, 40)]
    means = np.r_[front, [[3.0, 0.0, 2.0]], back]
    scales = np.r_[np.full((40, 3), 0.01), np.full((1, 3), 0.02), np.full((40, 3), 5.0)]
    return GaussianScene(means=means, quats=np.tile([1.0, 0, 0, 0], (81, 1)), scales=scales,
                         opacities=np.full(81, 0.8), sh_dc=rng.normal(size=(81, 3)))


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_a_back_layer_drawn_per_splat_after_layers_that_drew_nothing(backend):
    """A front and a back layer drawn per splat (floaters at the lens, a far backdrop) with the one
    layer between them beyond the frame's reach, so it draws nothing: the back layer is prepared
    for its own span of the order (the compute backend refused the range the front's left,
    'range [41, 81) is outside the prepared span (0, 40)', found by random frames against the
    twin), and the frame is the twin's."""
    scene = _floaters_and_backdrop()
    cam, lens = look_at([0, 0, 0], [0, 0, 5], 64, 48, 60), Lens(2.0, 400.0)
    r = get_backend(backend, scene)
    try:
        gl = r.render(cam, lens, SLICED)
        assert [(l.first, l.end, l.lensed) for l in r.sliced_layers] == [(0, 40, True), (40, 41, False), (41, 81, True)]
    finally:
        r.release()
    ref = render_reference_sliced(scene, cam, lens, SLICED)
    assert ref.alpha.mean() > 0.05 and (ref.depth > 0).all()  # the backdrop, spread thin by its blur
    assert_matches_sliced_reference(gl, ref)


@pytest.mark.parametrize("scale", [2, 4, 8, 32])
def test_reduction_to_a_level_is_the_twins_chain_of_2x2_averages(scale):
    """slice_reduce.frag takes 4 × 4 a pass (two 2 × 2 averages at once, the level between not
    written) while that does not pass the level, the first pass only in the tiles the layer's
    blend marked (elsewhere the level is cleared of what an earlier layer left): on an image whose
    levels have odd sides, light in some tiles, the level equals slices.reduce2 applied log2(s)
    times (the blocks that stick out at the far edges averaged over the texels inside), to the
    texture unit's filtering precision (llvmpipe's bilinear fetch: about 2⁻¹⁶ relative)."""
    from dofview.rendering.sliced import TILE

    scene = load_scene(CARDS, progress=False)
    r = get_backend("quad", scene)
    try:
        r.draw(*_view(scene, 8.0, 48, 36), SLICED)
        d = r._sliced
        w, h = 202, 117  # 2 × 2 blocks stick out of the image's top; 4 × 4 ones out of the level between's right
        d._targets(w, h)
        rng = np.random.default_rng(scale)
        columns, rows = -(-w // TILE), -(-h // TILE)
        marks = (rng.uniform(size=(rows, columns)) < 0.6).astype(np.uint32)
        lit = np.kron(marks, np.ones((TILE, TILE), np.uint32))[:h, :w, None] > 0
        colour = np.where(lit, rng.uniform(0.0, 2.0, (h, w, 4)), 0.0).astype(np.float32)
        depth = np.where(lit, rng.uniform(0.0, 5.0, (h, w, 4)), 0.0).astype(np.float32)
        d.slice_colour.write(colour.tobytes())
        d.slice_depth.write(depth.tobytes())
        first = d._level(4 if scale >= 4 else 2)  # what an earlier layer left there
        first.reduced.clear(7.0, 7.0, 7.0, 7.0)
        d._marks.buffer.write(marks.tobytes())
        d._list_tiles((0, 0, w, h), d._marks)
        got_c, got_d, region = d._reduce_layer((0, 0, w, h), scale)
        want_c, want_d = colour, depth
        for _ in range(int(math.log2(scale))):
            want_c, want_d = slices.reduce2(want_c), slices.reduce2(want_d)
        assert region == (0, 0, -(-w // scale), -(-h // scale))
        lw, lh = got_c.size
        assert (lh, lw) == want_c.shape[:2] and 0.3 < lit.mean() < 0.9
        np.testing.assert_allclose(np.frombuffer(got_c.read(), np.float32).reshape(lh, lw, 4), want_c, rtol=1e-4, atol=1e-5)
        np.testing.assert_allclose(np.frombuffer(got_d.read(), np.float32).reshape(lh, lw, 4), want_d, rtol=1e-4, atol=1e-5)
    finally:
        r.release()


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_the_gathers_tap_prefix_changes_no_bit(backend, monkeypatch):
    """slice_gather.frag stops a tile's taps after the last one that a source within its reach can
    give weight (slice_occupancy.comp's largest |ρ| there; sliced._tap_uniform's table of
    LensCell.tap_onsets): every tap it skips has weight 0. Drawn with the table at every tap, the
    frames of the disk, a 6-bladed aperture and a refinement cell are the same bit for bit; with a
    table of one tap they are not (the table is in use). Without highlights, whose additive blend
    follows the GPU's order."""
    from dofview.rendering import sliced

    scene = load_scene(TWO_PLANES, progress=False)
    cam, lens = _view(scene, 16.0)
    cases = ((0, None), (6, None), (0, lens_cells(8, 0)[3]))

    def frames() -> list[np.ndarray]:
        r = get_backend(backend, scene)
        r.slice_rule = replace(SLICE_RULE, sprites=0.0)
        try:
            out = []
            for blades, cell in cases:
                r.draw(cam, lens, replace(SLICED, blades=blades), cell=cell)
                out.append(np.frombuffer(r.colour_tex.read(), np.float32).copy())
            assert len(r.sliced_layers) >= 8
            return out
        finally:
            r.release()

    table = sliced._tap_uniform
    quick = frames()

    def every_tap(cell, radius):
        data, prefix, count, reach = table(cell, radius)
        assert np.frombuffer(prefix, np.int32).min() < count or count == 1
        return data, np.full(sliced.MAX_PREFIX, count, np.int32).tobytes(), count, reach

    monkeypatch.setattr(sliced, "_tap_uniform", every_tap)
    every = frames()
    monkeypatch.setattr(sliced, "_tap_uniform", lambda cell, radius: (
        table(cell, radius)[0], np.ones(sliced.MAX_PREFIX, np.int32).tobytes(), *table(cell, radius)[2:]))
    one = frames()
    for q, e, o in zip(quick, every, one):
        assert np.array_equal(q, e)
        assert not np.array_equal(q, o)


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_at_aperture_zero_sliced_is_the_pinhole(backend):
    """One layer, not blurred: the trained blend (the per-splat mode at A = 0, the frame's τ), its
    depth the pinhole's; a real lens's layers at a tiny aperture (every pixel's blur < ½ px) too."""
    scene = load_scene(CARDS, progress=False)
    cam, lens = _view(scene, 16.0)
    pin_lens = Lens(lens.focus, 0.0)
    r = get_backend(backend, scene)
    try:
        pin = r.render(cam, pin_lens, RenderSettings(dof="splat"))
        sliced = r.render(cam, pin_lens, SLICED)
        assert len(r.sliced_layers) == 1 and r.sliced_layers[0].radius == 0.0
        tiny = r.render(cam, replace(lens, aperture=lens.aperture * 1e-3), SLICED)
        assert len(r.sliced_layers) == 1
        blurred = r.render(cam, lens, SLICED)
    finally:
        r.release()
    assert psnr(sliced.rgba, pin.rgba) >= 60.0
    np.testing.assert_allclose(sliced.depth, pin.depth, rtol=1e-5, atol=1e-6)
    assert psnr(tiny.rgba, pin.rgba) >= 60.0
    np.testing.assert_allclose(blurred.depth, pin.depth, rtol=1e-4, atol=1e-6)  # the depth stays the pinhole's


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_each_gaussian_is_counted_once(backend):
    scene = load_scene(CARDS, progress=False)
    cam, lens = _view(scene, 16.0)
    r = get_backend(backend, scene)
    try:
        r.draw(cam, Lens(lens.focus, 0.0), RenderSettings(dof="splat", tau=0.0), count=True)
        pinhole = r.stats.drawn
        r.draw(cam, lens, RenderSettings(tau=0.0), count=True)
        assert len(r.sliced_layers) > 8
    finally:
        r.release()
    assert r.stats.drawn == pinhole > 0


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_an_empty_scene_draws_an_empty_frame(backend):
    scene = load_scene(CARDS, progress=False)
    r = get_backend(backend, scene.subset(np.zeros(0, np.int64)))
    try:
        cam, lens = _view(scene, 16.0, 64, 48)
        frame = r.render(cam, lens, SLICED)
    finally:
        r.release()
    assert frame.alpha.max() == 0.0 and frame.depth.max() == 0.0


def test_slanted_floor_follows_the_cpu_twin():
    """A uniform grey floor from z = 0.5 to 9 crosses many layers: the GL path shows the numpy
    twin's profile down the floor (tests/test_slices.py holds the twin to the thin lens there),
    adding no bands of its own (reduced-resolution levels, guard band, screen boxes)."""
    scene, cam, lens = receding_floor(160, 120, 10.0)
    r = get_backend("quad", scene)
    try:
        gl = r.render(cam, lens, SLICED)
        assert len(r.sliced_layers) >= 10 and len({l.scale for l in r.sliced_layers}) >= 3
    finally:
        r.release()
    ref = render_reference_sliced(scene, cam, lens, SLICED)
    rows, cols = np.arange(60, 118), slice(50, 110)
    np.testing.assert_allclose(gl.alpha[rows, cols].mean(axis=1), ref.alpha[rows, cols].mean(axis=1), atol=2e-3)
    np.testing.assert_allclose(gl.rgba[rows, cols, :3].mean(axis=(1, 2)), ref.rgba[rows, cols, :3].mean(axis=(1, 2)),
                               atol=2e-3)


def test_a_frame_filling_near_wall_keeps_its_blurred_coverage():
    """A beige wall 0.5 units from the lens fills the 80 × 60 frame but for a central opening onto
    a blue plane in focus at 3; the wall's CoC is 20 px. The thin lens blurs the opening's rim and
    keeps the wall opaque at the frame border; the sliced mode agrees with a 48-sample
    accumulation of the lens on the wall's coverage (read from the red channel of the blend, 0.3
    on the plane, 0.8 on the wall), where per-splat depth of field leaves holes."""
    parts = Parts.empty()
    add_panel(parts, 2, 3.0, {0: (-2.5, 2.5), 1: (-2.0, 2.0)}, (0.3, 0.5, 0.8), spacing=0.05)
    g = np.mgrid[-0.5:0.5:0.01, -0.4:0.4:0.01].reshape(2, -1).T
    wall = g[(np.abs(g[:, 0]) > 0.12) | (np.abs(g[:, 1]) > 0.09)]
    parts.add(np.c_[wall, np.full(len(wall), 0.5)], 0.006, (0.8, 0.75, 0.6), 0.98)
    scene = parts.build("srgb", "near wall")
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 80, 60, 70.0)
    lens = Lens(3.0, 2 * 20.0 / (1 / 0.5 - 1 / 3.0))
    r = get_backend("quad", scene)
    try:
        truth = make_references(r, cam, lens, RenderSettings(), 48, False, lambda: None).physical
        sliced = r.render(cam, lens, SLICED)
        anchor = r.render(cam, lens, ANCHOR)
    finally:
        r.release()

    def coverage(frame):
        return (encode(frame.rgba[..., 0].astype(np.float64)) - 0.3) / 0.5

    border = np.r_[0:8, 52:60]  # rows of wall only, up to the frame border
    c_truth, c_sliced = coverage(truth), coverage(sliced)
    assert c_truth[border].min() > 0.85
    assert c_sliced[border].min() > c_truth[border].min() - 0.05  # no room showing through there
    err = np.abs(c_sliced - c_truth)
    assert err.max() < 0.2 and err.mean() < 0.05  # the opening's blurred rim too
    assert np.abs(coverage(anchor) - c_truth).mean() > 2 * err.mean()  # (what the test tells apart)
    assert psnr(sliced.rgba, truth.rgba) >= 30.0


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_floaters_at_the_lens_do_not_fog_the_frame(backend):
    """30 small floaters (σ 0.004, opacity 0.5) 0.08–0.3 units from the lens in front of a plane in
    focus at 3, 80 × 60: their CoC runs to 73 and 146 px, and through the lens they all but vanish.
    Sliced (at 4 px all of them: the frame is 80 px) or drawn per splat beyond the frame
    (SliceRule.huge: 8 of them at 8 px), each is spread over its own CoC as the lens spreads it,
    instead of leaving discs or a veil: within 0.03 of the 48-sample accumulation everywhere (the
    pinhole: 0.32; measured 0.027, within the 48 samples' own noise: 0.015 / 0.016 against 64) and
    ≥ 45 dB (measured 51.3 / 51.0 dB against 64 samples; with a quarter of the frame as the
    threshold, every floater drawn per splat, 41.8 / 48.9)."""
    parts = Parts.empty()
    add_panel(parts, 2, 3.0, {0: (-2.5, 2.5), 1: (-2.0, 2.0)}, (0.3, 0.5, 0.8), spacing=0.05)
    rng = np.random.default_rng(3)
    d = rng.uniform(0.08, 0.3, 30)
    parts.add(np.c_[rng.uniform(-0.35, 0.35, 30) * d, rng.uniform(-0.25, 0.25, 30) * d, d], 0.004,
              rng.uniform(0.3, 0.9, (30, 3)), 0.5)
    scene = parts.build("srgb", "floaters")
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 80, 60, 70.0)
    r = get_backend(backend, scene)
    try:
        pin = r.render(cam, Lens(3.0, 0.0), SLICED)
        for blur in (4.0, 8.0):  # px at depth 1
            lens = Lens(3.0, 2 * blur / (1 / 1.0 - 1 / 3.0))
            truth = make_references(r, cam, lens, RenderSettings(), 48, False, lambda: None).physical
            sliced = r.render(cam, lens, SLICED)
            assert r.sliced_layers[0].lensed == (blur == 8.0)  # the floaters beyond 80 px of CoC, per splat
            assert np.abs(pin.rgba - truth.rgba).max() > 0.3  # (what the test tells apart)
            assert np.abs(sliced.rgba - truth.rgba).max() < 0.03
            assert psnr(sliced.rgba, truth.rgba) >= 45.0
    finally:
        r.release()


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_a_cluster_cut_by_the_frame_border_is_blurred_from_its_guard_band(backend):
    """60 leaves 0.30–0.33 units from the lens, half of them beyond the right border of an 80 × 60
    frame, before a plane in focus at 3: their CoC is 40 px. The layer is blended into a guard
    band beyond the frame (slices.guard_band: 32 px), so that the blur brings in what lies there
    and nothing more: within 1 dB of the CPU twin's 40 dB agreement, ≥ 40 dB from the 64-sample
    lens (measured 42.7), where repeating the frame's edge instead gives 34.2 dB."""
    parts = Parts.empty()
    add_panel(parts, 2, 3.0, {0: (-2.5, 2.5), 1: (-2.0, 2.0)}, (0.3, 0.5, 0.8), spacing=0.05)
    rng = np.random.default_rng(3)
    d = rng.uniform(0.3, 0.33, 60)
    parts.add(np.c_[rng.uniform(0.35, 0.75, 60) * d, rng.uniform(-0.1, 0.1, 60) * d, d], 0.006, (0.2, 0.6, 0.1), 0.9)
    scene = parts.build("srgb", "cluster")
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 80, 60, 70.0)
    lens = Lens(3.0, 2 * 40.0 / (1 / 0.3 - 1 / 3.0))
    sliced_all = replace(SLICE_RULE, huge=math.inf)  # the guard band of a sliced layer, every splat sliced
    r = get_backend(backend, scene)
    try:
        truth = make_references(r, cam, lens, RenderSettings(), 64, False, lambda: None).physical
        r.slice_rule = sliced_all
        sliced = r.render(cam, lens, SLICED)
        assert r._sliced.guard == 32 and r.read().rgba.shape == (60, 80, 4)
    finally:
        r.release()
    assert psnr(sliced.rgba, render_reference_sliced(scene, cam, lens, rule=sliced_all).rgba) >= MIN_PSNR
    repeated = render_reference_sliced(scene, cam, lens, rule=replace(sliced_all, guard=0.0))
    assert psnr(sliced.rgba, truth.rgba) >= 40.0
    assert psnr(sliced.rgba, truth.rgba) >= psnr(repeated.rgba, truth.rgba) + 5.0


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_a_bush_at_the_lens_is_carried_by_the_refinement(backend):
    """300 leaves 0.12–0.45 units from the lens (CoC 48–96 px against an 80 × 60 frame) over the
    upper left, before a wall in focus at 3: the case no single pass gets right. Through the lens
    the leaves hide each other; blurred as independent layers or as independent splats (the
    per-splat anchors; the default draws the splats blurred beyond the frame per splat) they
    over-cover: measured against the 64-sample lens at 4 and 8 px, the default 21.5 / 18.0 dB,
    with a quarter of the frame as the threshold 21.0 / 18.6, the best anchor 22.6 / 21.7, the
    pinhole 22.8 / 19.9. The refinement's passes share lens positions across the leaves: stage 4
    is 29.2 / 25.4 dB (≥ 3 dB over the pinhole, every anchor and the single pass asserted)."""
    parts = Parts.empty()
    add_panel(parts, 2, 3.0, {0: (-2.5, 2.5), 1: (-2.0, 2.0)}, (0.8, 0.75, 0.3), spacing=0.05)
    rng = np.random.default_rng(5)
    d = rng.uniform(0.12, 0.45, 300)
    parts.add(np.c_[rng.uniform(-0.9, 0.1, 300) * d, rng.uniform(0.0, 0.8, 300) * d, d], 0.012,
              np.array([0.2, 0.5, 0.15]) * rng.uniform(0.6, 1.2, (300, 1)), 0.9)
    scene = parts.build("srgb", "bush")
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 80, 60, 70.0)
    r = get_backend(backend, scene)
    try:
        pinhole = r.render(cam, Lens(3.0, 0.0), SLICED)
        for blur in (4.0, 8.0):  # px at depth 1
            lens = Lens(3.0, 2 * blur / (1 / 1.0 - 1 / 3.0))
            truth = make_references(r, cam, lens, RenderSettings(), 64, False, lambda: None).physical
            sliced = r.render(cam, lens, SLICED)
            anchors = [psnr(r.render(cam, lens, replace(ANCHOR, k=k)).rgba, truth.rgba) for k in (1 / 9, 1 / 4, 1.0)]
            stage4 = render_lens_samples(r, cam, lens, SLICED, 4)
            assert psnr(sliced.rgba, render_reference_sliced(scene, cam, lens).rgba) >= MIN_PSNR
            single = psnr(sliced.rgba, truth.rgba)
            assert psnr(stage4.rgba, truth.rgba) >= max(psnr(pinhole.rgba, truth.rgba), single, *anchors) + 3.0
    finally:
        r.release()


def test_floaters_drawn_per_splat_before_a_slanted_floor_leave_no_discs():
    """20 floaters 0.1–0.3 units from the lens over a floor crossing many layers (160 × 120, CoC
    of the floaters up to 124 px). In the pinhole each hides the floor under it, but through the
    lens it hides nothing: sliced, the resolve fills the floor's cuts between layers only halfway
    under each and every floater leaves a disc of seams (33.4 dB against the 48-sample lens: the
    default, whose threshold is the frame, slices them); drawn per splat (SliceRule.huge a quarter
    of the frame), they spread thin over the floor as the lens spreads them: 36.2 dB measured
    (≥ 35 and ≥ 2 dB over every splat sliced asserted). The default keeps the frame as its
    threshold for the frame-filling near wall, which drawn per splat fogs (docs/BENCHMARKS.md,
    "Depth of field in places")."""
    floor, cam, lens = receding_floor(160, 120, 10.0)
    rng = np.random.default_rng(4)
    d = rng.uniform(0.1, 0.3, 20)
    px = np.stack([rng.uniform(0.1, 0.9, 20) * 160, rng.uniform(0.55, 0.95, 20) * 120], 1)
    near = np.stack([(px[:, 0] - cam.cx) / cam.fx * d, (px[:, 1] - cam.cy) / cam.fy * d, d], 1)
    parts = Parts.empty()
    parts.add((near - cam.T) @ cam.R, 0.004, rng.uniform(0.3, 0.9, (20, 3)), 0.5)
    floaters = parts.build(floor.colour_space, "floaters")
    scene = GaussianScene(*(np.concatenate([getattr(floor, f), getattr(floaters, f)])
                            for f in ("means", "quats", "scales", "opacities", "sh_dc")),
                          colour_space=floor.colour_space, name="floor and floaters")
    quarter = replace(SLICE_RULE, huge=0.25)
    r = get_backend("quad", scene)
    try:
        truth = make_references(r, cam, lens, RenderSettings(), 48, False, lambda: None).physical
        r.slice_rule = quarter
        sliced = r.render(cam, lens, SLICED)
        assert r.sliced_layers[0].lensed
    finally:
        r.release()
    assert psnr(sliced.rgba, render_reference_sliced(scene, cam, lens, rule=quarter).rgba) >= MIN_PSNR
    all_sliced = render_reference_sliced(scene, cam, lens, rule=replace(SLICE_RULE, huge=math.inf))
    assert psnr(sliced.rgba, truth.rgba) >= 35.0
    assert psnr(sliced.rgba, truth.rgba) >= psnr(all_sliced.rgba, truth.rgba) + 2.0


def test_sliced_beats_the_published_kernels_against_the_thin_lens():
    """burger (the stand-in in tests/data), one study view at 120 × 90, focus at the median depth,
    largest blur in view 12 px, truth from 64 lens samples in linear light: the default beats the
    best of the per-splat anchors (k = 1/9, 1/4, 1) by ≥ 2 dB. (Measured here +4.3 dB; the five
    real scenes: docs/BENCHMARKS.md, "Sliced depth of field".)"""
    import warnings

    from dofview.bench.sliced_study import cases_for
    from dofview.bench.study import ANCHOR_KS, study_views

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = load_scene(ROOT / "tests" / "data" / "burger.ply", progress=False)
    cam = study_views(scene, 1, 120, 90)[0]
    r = get_backend("quad", scene)
    try:
        lens = cases_for(r, cam, blurs=(12.0,))[0]
        truth = make_references(r, cam, lens, RenderSettings(), 64, False, lambda: None).physical

        def score(st):
            f = r.render(cam, lens, st)
            return psnr(display(f.rgba, f.encoded, Tonemap()), display(truth.rgba, truth.encoded, Tonemap()))

        best = max(score(replace(ANCHOR, k=k)) for k in ANCHOR_KS.values())
        sliced = score(RenderSettings())
    finally:
        r.release()
    assert sliced >= best + 2.0, (sliced, best)


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_bladed_aperture_blurs_a_point_into_the_polygon_turned_in_front_of_focus(backend):
    """One small bright splat far behind focus and one far in front: each bokeh is the aperture, a
    pentagon whose corner points along the rotation behind focus and against it in front (a lens
    images a point before the focus plane through the aperture turned half a turn), matching the
    CPU reference."""
    parts = Parts.empty()
    front = 1.0 / (1.0 + 5.0 / 6.0)  # as far in front of focus in 1/z as z = 6 is behind it
    parts.add(np.array([[-0.9, 0.0, 6.0], [0.18 * front, 0.0, front]]), 0.002, np.array([[1.0, 1.0, 1.0]] * 2), 0.99)
    scene = parts.build("srgb", "points")
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 128, 96, 40.0)
    lens = Lens(1.0, 2 * 20.0 / (1 - 1 / 6.0))  # a 20 px CoC at z = 6 and in front
    pentagon = RenderSettings(blades=5, blade_rotation=0.0)
    r = get_backend(backend, scene)
    try:
        disk = r.render(cam, lens, SLICED).alpha
        five = r.render(cam, lens, pentagon).alpha
    finally:
        r.release()
    ref = render_reference_sliced(scene, cam, lens, pentagon).alpha
    assert psnr(five, ref) >= MIN_PSNR
    def centre(img, half):
        part = img[:, :64] if half == 0 else img[:, 64:]
        yy, xx = np.mgrid[:96, :64]
        return (int(round(float((yy * part).sum() / part.sum()))), int(round(float((xx * part).sum() / part.sum()))) + 64 * half)

    def reach(img, at, step) -> int:
        """Pixels from ``at`` to the bokeh's edge (half its peak) along ``step`` (dy, dx)."""
        n, peak = 0, img[:, 64 * (at[1] >= 64):][:, :64].max()
        while 0 <= at[0] + (n + 1) * step[0] < 96 and 0 <= at[1] + (n + 1) * step[1] < 128 and \
                img[at[0] + (n + 1) * step[0], at[1] + (n + 1) * step[1]] > 0.5 * peak:
            n += 1
        return n

    for half, corner in ((0, (0, 1)), (1, (0, -1))):  # behind focus the corner at +x, in front at −x
        at = centre(disk, half)
        flat = (-corner[0], -corner[1])  # opposite a corner of a pentagon: the middle of an edge
        assert abs(reach(five, at, corner) - reach(disk, at, corner)) <= 1
        assert reach(five, at, flat) <= round(0.9 * reach(disk, at, flat)) and reach(disk, at, flat) >= 15


def test_a_lens_cell_pass_and_the_whole_lens():
    """Refinement's passes go through the renderer: a cell's draw is its kernel at the whole
    lens's CoC (the reference of the same cell), and the per-splat mode refuses a cell."""
    scene = load_scene(CARDS, progress=False)
    cam, lens = _view(scene, 12.0, 96, 72)
    cell = lens_cells(4)[1]
    r = get_backend("quad", scene)
    try:
        u, v = cell.point * 0.5 * lens.diameter(cam.fx)
        shifted = cam.lens_shifted(float(u), float(v), lens.focus)
        r.draw(shifted, lens, SLICED, cell=cell)
        gl = r.read()
        with pytest.raises(ValueError):
            r.draw(shifted, lens, RenderSettings(dof="splat"), cell=cell)
    finally:
        r.release()
    ref = render_reference_sliced(scene, shifted, lens, SLICED, cell=cell)
    assert psnr(gl.rgba, ref.rgba) >= MIN_PSNR


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_a_lens_cell_pass_blurs_the_huge_coc_layers_by_its_share_of_the_lens(backend):
    """A refinement pass whose plan has a front layer drawn per splat (a cloud at the lens before a
    backdrop): it is blurred by the cell's share of the aperture in the GL path and in the twin
    alike (the twin blurred it by the whole lens: 37.8 dB here, and 41.5 dB with 1 % of the depth
    within 1e-3 on the random frame where random lens-cell frames found it)."""
    rng = np.random.default_rng(1)
    means = np.r_[np.c_[rng.uniform(-0.12, 0.12, (200, 2)), rng.uniform(0.2, 0.3, 200)],  # at the lens
                  np.c_[rng.uniform(-4, 4, (300, 2)), rng.uniform(6, 8, 300)]]
    scales = np.r_[np.full((200, 3), 0.1), np.full((300, 3), 0.4)]
    scene = GaussianScene(means=means, quats=np.tile([1.0, 0, 0, 0], (500, 1)), scales=scales,
                          opacities=np.full(500, 0.8), sh_dc=rng.normal(size=(500, 3)))
    cam, lens = look_at([0, 0, 0], [0, 0, 5], 64, 48, 60), Lens(2.0, 200.0)
    cell = lens_cells(4)[1]
    u, v = cell.point * 0.5 * lens.diameter(cam.fx)
    shifted = cam.lens_shifted(float(u), float(v), lens.focus)
    r = get_backend(backend, scene, packed=False)
    try:
        r.draw(shifted, lens, SLICED, cell=cell)
        gl = r.read()
        assert r.sliced_layers[0].lensed and r.sliced_layers[0].end == 200
    finally:
        r.release()
    ref = render_reference_sliced(scene, shifted, lens, SLICED, cell=cell)
    assert ref.alpha.mean() > 0.5
    assert_matches_sliced_reference(gl, ref)


def test_settings_round_trip_and_refuse_nonsense():
    s = RenderSettings(dof="sliced", blades=7, blade_rotation=12.5)
    assert RenderSettings.from_dict(json.loads(json.dumps(s.to_dict()))) == s
    assert "--blades" in s.to_args() and "--dof" not in s.to_args()  # sliced is the default
    assert "--dof" in RenderSettings(dof="splat").to_args()
    assert RenderSettings.from_dict({"tau": 0.0}).dof == "splat"  # a header from before the mode was recorded
    assert RenderSettings().dof == "sliced"
    for bad in ({"dof": "layered"}, {"blades": 2}, {"blade_rotation": float("nan")}):
        with pytest.raises(DofviewError):
            RenderSettings(**bad)
    assert SLICE_RULE.limit == 3.0


def test_cli_renders_sliced_and_records_it(tmp_path):
    exr = tmp_path / "s.exr"
    assert main(["render", str(CARDS), "--cameras", str(ROOT / "samples" / "cards_cameras.json"), "--width", "96",
                 "--height", "72", "--blur", "10", "--blades", "5", "-o", str(exr)]) == 0
    channels, header = read_exr(exr)
    render = json.loads(header["dofview:render"])
    assert render["dof"] == "sliced" and render["blades"] == 5
    assert channels["A"].mean() > 0.1 and np.isfinite(channels["Z"]).all()
    with pytest.raises(SystemExit) as bad:
        main(["render", str(CARDS), "--dof", "blur", "-o", str(tmp_path / "x.exr")])
    assert bad.value.code == 2
    assert not (tmp_path / "x.exr").exists()


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_the_kernel_tables_are_made_once_per_aperture_and_lens_cell(backend, monkeypatch):
    """The N(ρ) tables (LensCell.norms) of an aperture are made by its first sliced frame only, and
    those of refinement's lens cells by the first stage that uses them (issue 28: every sliced frame
    made and uploaded them again, for a new LensCell each draw)."""
    scene = load_scene(CARDS, progress=False)
    cam, lens = _view(scene, 12.0, 64, 48)
    made = []
    norms = slices.LensCell.norms
    monkeypatch.setattr(slices.LensCell, "norms", lambda cell, *a, **k: made.append(cell) or norms(cell, *a, **k))
    # apertures no other test draws (the tables are kept for the process: one aperture, one set)
    settings, other = (RenderSettings(blades=7, blade_rotation=float(backend == "quad") + a) for a in (11.25, 13.5))
    r = get_backend(backend, scene)
    try:
        r.draw(cam, lens, settings)
        assert len(made) == 2  # the fine table and the frame's range
        made.clear()
        r.draw(cam, lens, settings)
        r.draw(cam, lens, settings)
        assert not made
        r.draw(cam, lens, other)  # another aperture: its own tables
        assert len(made) == 2
        render_lens_samples(r, cam, lens, settings, 3)
        assert len(made) > 2
        made.clear()
        render_lens_samples(r, cam, lens, settings, 3)
        assert not made
    finally:
        r.release()


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_at_aperture_zero_no_gaussian_is_planned(backend, monkeypatch):
    """A = 0 is the pinhole frame: the plan looks at no Gaussian (issue 28: it planned every one)."""
    scene = load_scene(CARDS, progress=False)
    cam, lens = _view(scene, 12.0, 64, 48)

    def refuse(*args, **kwargs):
        raise AssertionError("a Gaussian was planned at A = 0")

    r = get_backend(backend, scene)
    try:
        pin = r.render(cam, Lens(lens.focus, 0.0), RenderSettings(dof="splat"))
        monkeypatch.setattr(slices, "plan_layers", refuse)
        monkeypatch.setattr(slices, "screen_boxes", refuse)
        monkeypatch.setattr(type(r), "front_to_back", refuse)
        monkeypatch.setattr(layer_plan.GpuLayerPlan, "measure", refuse)
        sliced = r.render(cam, Lens(lens.focus, 0.0), SLICED)
        assert [(l.first, l.end, l.radius) for l in r.sliced_layers] == [(0, scene.count, 0.0)]
    finally:
        r.release()
    assert psnr(sliced.rgba, pin.rgba) >= 60.0


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_the_pass_profile_times_each_kind_and_draws_the_same_frame(backend):
    """Renderer.sliced_pass_times waits for the GL after each kind of pass and times it: the frame
    it leaves is the plain draw's, bit for bit (two planes at 16 px: reduced layers with highlight
    sprites, full-resolution layers; no sprites, whose additive blend follows the GPU's order), it
    names the kinds a layered frame draws and no others, and only the sliced mode has a profile."""
    from dofview.bench.sliced_study import PASS_KINDS

    scene = load_scene(TWO_PLANES, progress=False)
    cam, lens = _view(scene, 16.0)
    r = get_backend(backend, scene)
    r.slice_rule = replace(SLICE_RULE, sprites=0.0)
    try:
        r.draw(cam, lens, SLICED)
        plain = np.frombuffer(r.colour_tex.read(), np.float32).copy(), np.frombuffer(r.depth_tex.read(), np.float32).copy()
        times = r.sliced_pass_times(cam, lens, SLICED)
        timed = np.frombuffer(r.colour_tex.read(), np.float32), np.frombuffer(r.depth_tex.read(), np.float32)
        assert np.array_equal(plain[0], timed[0]) and np.array_equal(plain[1], timed[1])
        assert {layer.scale for layer in r.sliced_layers} - {1}, "the case must have reduced layers"
        assert set(times) <= set(PASS_KINDS)
        drawn = {"plan", "clear", "blend", "list tiles", "visible", "visible + prepare", "reduce", "prepare", "empty",
                 "occupancy", "gather", "upsample", "resolve"}
        assert drawn <= {k for k, ms in times.items() if ms > 0.0}, times
        with pytest.raises(ValueError, match="sliced"):
            r.sliced_pass_times(cam, lens, RenderSettings(dof="splat"))
        assert r._sliced.timer is None  # the profile leaves no timer behind
    finally:
        r.release()


def test_the_pass_profile_command_writes_its_table_and_figure(tmp_path, capsys):
    """``python -m dofview.bench.sliced_study passes`` prints a row per backend and case (the
    kinds' columns, the pinhole and sliced frames) and writes the stacked-bar figure."""
    from PIL import Image

    from dofview.bench.sliced_study import PASS_KINDS
    from dofview.bench.sliced_study import main as study

    png = tmp_path / "passes.png"
    assert study(["passes", str(TWO_PLANES), "--width", "96", "--height", "64", "--reps", "1",
                  "--raster", "quad", "--figure", str(png)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    head, rows = lines[0].split("\t"), [line.split("\t") for line in lines[1:]]
    assert head[-len(PASS_KINDS):] == list(PASS_KINDS)
    assert [(row[1], row[2]) for row in rows] == [("quad", "A=100"), ("quad", "16 px")]
    for row in rows:
        assert float(row[head.index("pinhole ms")]) > 0 and float(row[head.index("sliced ms")]) > 0
        assert float(row[head.index("blend")]) > 0
        kinds = sum(float(v) for v in row[-len(PASS_KINDS):])
        assert kinds == pytest.approx(float(row[head.index("profiled ms")]), abs=0.1 * len(PASS_KINDS))
    with Image.open(png) as im:
        assert im.width > 600 and im.height > 100
