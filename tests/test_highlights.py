"""Highlights in the sliced mode (issue 32): a small bright source far out of focus is drawn as a
full-resolution sprite with the gather's own kernel (slices.highlights, sliced.py's sprite pass), so
its bokeh is a disc (or the polygon) with the lens's edge on both backends, refinement's lens cells
tile that disc instead of showing copies, every sprite keeps its pixel's light, and the GL path
stays the CPU twin's."""

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from dofview.bench.metrics import edge_width, psnr, radial_profile
from dofview.bench.primitives import Parts, add_panel
from dofview.bench.synth import single_gaussian
from dofview.camera import look_at
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.io import load_scene
from dofview.io.cameras import load_cameras_json
from dofview.lens import Lens
from dofview.rendering import get_backend, slices
from dofview.rendering.accumulate import accumulate, lens_samples
from dofview.rendering.progressive import lens_cells, pass_settings, render_lens_samples
from dofview.rendering.reference import render_reference_sliced
from dofview.rendering.slices import SLICE_RULE, Aperture, SliceRule
from dofview.tonemap import Tonemap
from dofview.tonemap.display import display

ROOT = Path(__file__).resolve().parents[1]
SIZE, BLUR = 160, 40.0  # a point 40 px out of focus: its layer is gathered at 1/16 resolution
OFF = replace(SLICE_RULE, sprites=0.0)  # the sliced mode without sprites (before issue 32)


def _point(colour_space: str = "linear", z: float = 2.0, x: float = 0.0):
    """One small bright Gaussian (σ = 1.5 px) at depth ``z`` seen from the origin, focus 10, a CoC of
    BLUR px at z = 2; HDR radiance 20 in a linear scene, white in an sRGB one."""
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), SIZE, SIZE, 50.0)
    scale = 1.5 * z / cam.fx
    colour = (20.0,) * 3 if colour_space == "linear" else (1.0,) * 3
    scene = single_gaussian((x, 0.0, z), scale, 0.95, colour, colour_space=colour_space)
    return scene, cam, Lens(10.0, 2.0 * BLUR / (1.0 / 2.0 - 1.0 / 10.0))


def _light(rgba: np.ndarray) -> np.ndarray:
    """(H, W) float64 the largest linear channel."""
    return rgba[..., :3].max(axis=-1).astype(np.float64)


def _thin_lens(r, cam, lens, blades: int = 0, samples: int = 1024) -> np.ndarray:
    """The thin lens's image (accumulated pinholes, linear light) through a disk or, for a
    centrally symmetric polygon, the sunflower's points inside it."""
    points = lens_samples(samples)
    points = points[Aperture(blades).inside(points)]
    return accumulate(lambda c: r.render(c, Lens(lens.focus, 0.0), pass_settings(RenderSettings())), cam, lens,
                      len(points), points=points).rgba


@pytest.fixture(scope="module")
def truths():
    """The thin lens's image of the point, per colour space (the quad backend's pinholes)."""
    out = {}
    for space in ("linear", "srgb"):
        scene, cam, lens = _point(space)
        r = get_backend("quad", scene)
        try:
            out[space] = _thin_lens(r, cam, lens)
        finally:
            r.release()
    return out


@pytest.mark.parametrize("backend", ["quad", "compute"])
@pytest.mark.parametrize("space", ["linear", "srgb"])
def test_a_bright_points_bokeh_has_the_lenss_edge(backend, space, truths):
    """The disc's 90 → 10 % edge, measured on both backends: linear 4.0 px through the lens and
    with sprites, 30.0 without them (the point gathered at 1/16 resolution); sRGB 3.0, 3.5 and
    23.5. Its radius is the lens's and, in a linear scene, its light the pinhole's."""
    scene, cam, lens = _point(space)
    r = get_backend(backend, scene)
    try:
        sliced = r.render(cam, lens, RenderSettings()).rgba
        r.slice_rule = OFF
        before = r.render(cam, lens, RenderSettings()).rgba
        pin = r.render(cam, Lens(lens.focus, 0.0), RenderSettings()).rgba
    finally:
        r.release()
    truth = _light(truths[space])
    edge, lens_edge = edge_width(_light(sliced), BLUR), edge_width(truth, BLUR)
    assert edge <= 1.5 * lens_edge, (edge, lens_edge)
    assert edge_width(_light(before), BLUR) > 2.0 * lens_edge  # what the sprites change
    r_s, q_s = radial_profile(_light(sliced), BLUR)
    r_t, q_t = radial_profile(truth, BLUR)
    half = lambda r, q: r[np.nonzero(q >= 0.5)[0].max()]  # noqa: E731
    assert abs(half(r_s, q_s) - half(r_t, q_t)) <= 1.0  # the disc's radius, the lens's
    if space == "linear":
        assert _light(sliced).sum() == pytest.approx(_light(pin).sum(), rel=1e-3)


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_a_bladed_aperture_draws_a_highlight_as_the_polygon_with_its_edges(backend):
    """Six blades, the first corner along +x: through the centre, along x the bokeh reaches a
    corner and along y the middle of an edge, as through the lens (measured 39 and 34 px, both),
    with the lens's edge (4 px along either, against 16 and 15 without sprites)."""
    scene, cam, lens = _point()
    hexagon = RenderSettings(blades=6, blade_rotation=0.0)
    r = get_backend(backend, scene)
    try:
        sliced = _light(r.render(cam, lens, hexagon).rgba)
        r.slice_rule = replace(slices.rule_for(6), sprites=0.0)
        before = _light(r.render(cam, lens, hexagon).rgba)
        r.slice_rule = None
        truth = _light(_thin_lens(r, cam, lens, blades=6))
    finally:
        r.release()

    def cuts(img):
        """(50 % reach, 90 → 10 % edge) px along +x and +y from the centroid."""
        yy, xx = np.mgrid[:SIZE, :SIZE]
        cy, cx = int(round((img * yy).sum() / img.sum())), int(round((img * xx).sum() / img.sum()))
        out = []
        for line in (img[cy, cx:], img[cy:, cx]):
            q = line / line[:10].mean()
            out.append((int(np.nonzero(q >= 0.5)[0].max()),
                        int(np.nonzero(q >= 0.1)[0].max()) - int(np.nonzero(q >= 0.9)[0].max())))
        return out

    got, want, old = cuts(sliced), cuts(truth), cuts(before)
    assert want[1][0] <= want[0][0] - 2  # the truth is the hexagon: the flat side nearer than the corner
    for (reach, edge), (reach_t, edge_t), (_, edge_old) in zip(got, want, old):
        assert abs(reach - reach_t) <= 1
        assert edge <= max(1.5 * edge_t, edge_t + 2)
        assert edge_old > 2 * edge_t


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_refinement_stage_8_fills_the_disc_without_copies(backend, truths):
    """Eight lens cells, each drawn through its own exact shape at full resolution, tile the
    point's disc: its core is even (measured coefficient of variation 0.9 % against 9.8 % without
    sprites, where each cell's blob at its coarse level shows as a copy), its radial profile flat
    (spread 2 % against 14 %) and closer to the lens (37.6 dB against 22.2)."""
    scene, cam, lens = _point()
    r = get_backend(backend, scene)
    try:
        staged = _light(render_lens_samples(r, cam, lens, RenderSettings(), 8).rgba)
        r.slice_rule = OFF
        before = _light(render_lens_samples(r, cam, lens, RenderSettings(), 8).rgba)
    finally:
        r.release()
    truth = _light(truths["linear"])

    def core_spread(img):
        yy, xx = np.mgrid[:SIZE, :SIZE] + 0.5
        cy, cx = (img * yy).sum() / img.sum(), (img * xx).sum() / img.sum()
        core = img[np.hypot(yy - cy, xx - cx) < 0.75 * BLUR]
        return core.std() / core.mean()

    assert core_spread(staged) < 0.02 < core_spread(before)
    rr, q = radial_profile(staged, BLUR)
    inner = q[(rr > 2.0) & (rr < 0.75 * BLUR)]
    assert inner.max() - inner.min() < 0.05  # flat: no ring of copies
    peak = truth.max()
    assert psnr(staged, truth, peak) >= psnr(before, truth, peak) + 6.0
    assert edge_width(staged, BLUR) <= 1.5 * edge_width(truth, BLUR)


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_every_sprite_keeps_its_pixels_light_through_any_kernel(backend):
    """The sprites' N(ρ) (slice_kernel.glsl's row-by-row exact sum) against the light of the
    pinhole: the disk, a pentagon turned, and cells of a refinement stage, at several blurs."""
    scene, cam, lens = _point()
    r = get_backend(backend, scene)
    try:
        for z in (2.0, 2.5, 4.0):  # CoC 40, 30 and 15 px (beyond 40, a quarter of the frame, no layer)
            scene_z, _, _ = _point(z=z)
            r.swap_scene(scene_z)
            pin = _light(r.render(cam, Lens(lens.focus, 0.0), RenderSettings()).rgba).sum()
            for settings in (RenderSettings(), RenderSettings(blades=5, blade_rotation=17.0)):
                img = _light(r.render(cam, lens, settings).rgba)
                assert img.sum() == pytest.approx(pin, rel=2e-3), (z, settings.blades)
            for cell in lens_cells(8)[::3]:
                u, v = cell.point * 0.5 * lens.diameter(cam.fx)
                shifted = cam.lens_shifted(float(u), float(v), lens.focus)
                seen = _light(r.render(shifted, Lens(lens.focus, 0.0), RenderSettings()).rgba).sum()
                r.draw(shifted, lens, RenderSettings(), cell=cell)
                assert _light(r.read().rgba).sum() == pytest.approx(seen, rel=2e-3), z
    finally:
        r.release()


def _lights_before_a_wall(colour_space: str):
    """Bright points (some HDR, some dim) of different depths in front of a textured wall, and a
    dark card between them: layers with sprites, layers of a level behind them, a front layer."""
    rng = np.random.default_rng(5)
    parts = Parts.empty()
    add_panel(parts, 2, 6.0, {0: (-2.5, 2.5), 1: (-2.0, 2.0)}, (0.3, 0.25, 0.2), spacing=0.12)
    parts.colours[-1] = rng.uniform(0.1, 0.5, parts.colours[-1].shape)
    add_panel(parts, 2, 1.4, {0: (-0.4, 0.0), 1: (-0.1, 0.3)}, (0.05, 0.1, 0.05), spacing=0.03)
    bright = 12.0 if colour_space == "linear" else 1.0
    points = np.column_stack([rng.uniform(-1.2, 1.2, 10), rng.uniform(-0.9, 0.9, 10), rng.uniform(2.0, 5.0, 10)])
    points[:, :2] *= points[:, 2:] / 4.0  # within the view
    colours = np.where(np.arange(10)[:, None] < 7, bright, 0.02) * rng.uniform(0.6, 1.0, (10, 3))
    parts.add(points, 0.006, colours, 0.95)
    return parts.build(colour_space, "lights")


@pytest.mark.parametrize("backend", ["quad", "compute"])
@pytest.mark.parametrize("space", ["linear", "srgb"])
def test_sprites_match_the_cpu_twin(backend, space):
    """Points before a wall, several layers with sprites and layers of a level behind them: the GL
    frame is the CPU twin's (slices.sliced_image: highlights, draw_sprites, a run of one layer) to
    ≥ 40 dB, and differs from the frame without sprites by more than 1 % of its peak."""
    scene = _lights_before_a_wall(space)
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 128, 96, 60.0)
    lens = Lens(1.2, 60.0)
    r = get_backend(backend, scene)
    try:
        gl = r.render(cam, lens, RenderSettings())
        r.slice_rule = OFF
        off = r.render(cam, lens, RenderSettings())
        scales = {layer.scale for layer in r.sliced_layers}
    finally:
        r.release()
    ref = render_reference_sliced(scene, cam, lens, RenderSettings())
    assert len(scales - {1}) >= 2  # reduced layers of several levels
    assert psnr(gl.rgba, ref.rgba) >= 40.0
    assert np.abs(gl.rgba - off.rgba).max() > 0.01 * gl.rgba[..., :3].max()  # the sprites drew something


def test_past_the_cap_highlights_stay_in_the_gather():
    """A cap of 3 sprites a frame: the rest of the points' light is gathered as before; nothing is
    lost and the twin takes the same number (GL's 3 are whichever the GPU appended first)."""
    scene = _lights_before_a_wall("linear")
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 128, 96, 60.0)
    lens = Lens(1.2, 60.0)
    few = replace(SLICE_RULE, sprites=3.0 / (128 * 96))
    assert slices.sprite_cap(few, 128, 96) == 3
    r = get_backend("quad", scene)
    try:
        r.slice_rule = few
        capped = r.render(cam, lens, RenderSettings()).rgba
        r.slice_rule = OFF
        off = r.render(cam, lens, RenderSettings()).rgba
        r.slice_rule = None
        full = r.render(cam, lens, RenderSettings()).rgba
    finally:
        r.release()
    for img in (capped, full):
        assert img[..., :3].sum() == pytest.approx(off[..., :3].sum(), rel=2e-3)
    assert 0.0 < np.abs(capped - off).sum() < np.abs(full - off).sum()
    twin = render_reference_sliced(scene, cam, lens, RenderSettings(), rule=few).rgba
    assert twin[..., :3].sum() == pytest.approx(off[..., :3].sum(), rel=2e-3)


def test_the_lamps_bulb_is_a_smooth_disc_and_keeps_its_light():
    """samples/lamp.ply, --blur 5% --focus inf at 240 × 180 against 128 lens samples: the bulb
    (HDR, radiance ~100) is drawn by sprites; the display image gains ≥ 5 dB over the sliced mode
    without them (measured 41.1 against 30.9 dB; linear 57.5 against 51.3), and the linear one does not lose
    (the bulb's layer composited on its own, so the wall behind it stays hidden: with the bulb's
    layer in a run with the wall, the resolve dimmed the bulb by 30 %)."""
    scene = load_scene(ROOT / "samples" / "lamp.ply", progress=False)
    cam = load_cameras_json(ROOT / "samples" / "lamp_cameras.json")[0].resized(240, 180)
    lens = Lens(1e9, 87.5)  # 5 % of the width at infinity
    r = get_backend("quad", scene)
    try:
        truth = accumulate(lambda c: r.render(c, Lens(lens.focus, 0.0), pass_settings(RenderSettings())), cam, lens,
                           128).rgba
        sliced = r.render(cam, lens, RenderSettings()).rgba
        r.slice_rule = OFF
        off = r.render(cam, lens, RenderSettings()).rgba
    finally:
        r.release()
    shown = {k: display(v, False, Tonemap()) for k, v in (("truth", truth), ("sliced", sliced), ("off", off))}
    assert psnr(shown["sliced"], shown["truth"]) >= psnr(shown["off"], shown["truth"]) + 5.0
    peak = float(truth[..., :3].max())
    assert psnr(sliced[..., :3], truth[..., :3], peak) >= psnr(off[..., :3], truth[..., :3], peak)
    assert sliced[..., :3].sum() == pytest.approx(truth[..., :3].sum(), rel=0.02)


def test_highlight_share_picks_points_and_bright_rims_not_even_surfaces():
    """slices.highlight_share: a lone point wholly, a dim one and an even surface (with a pixel a
    little brighter than it) not at all; an HDR disc's pixels, rim included, wholly."""
    rule = SLICE_RULE
    level = lambda img, s: img if s == 1 else level(slices.reduce2(img), s // 2)  # noqa: E731
    img = np.zeros((32, 32, 4))
    img[10, 13] = (1.0, 1.0, 1.0, 1.0)  # a point alone
    img[20:, :, :] = (0.5, 0.4, 0.3, 1.0)  # an even surface
    img[28, 28, :3] = 0.6  # a little brighter than it
    img[3, 30] = (0.008, 0.008, 0.008, 1.0)  # a dim point (below SliceRule.dim)
    f = slices.highlight_share(img, level(img, 4), 4, rule)
    assert f[10, 13] == 1.0 and f[3, 30] == 0.0
    assert np.all(f[20:27] == 0.0) and f[28, 28] == 0.0
    # an HDR source stands out of the level's neighbourhood by more than SliceRule.excess (by a
    # ratio of only ~5 at its rim); an even HDR surface does not
    yy, xx = np.mgrid[:32, :32] + 0.5
    hdr = np.full((32, 32, 4), 0.2)
    inside = np.hypot(yy - 16, xx - 16) < 8
    hdr[inside] = (50.0, 50.0, 50.0, 1.0)
    f = slices.highlight_share(hdr, level(hdr, 8), 8, rule)
    assert np.all(f[inside] == 1.0) and np.all(f[~inside] == 0.0)
    assert np.all(slices.highlight_share(hdr * 0 + 50.0, level(hdr * 0 + 50.0, 8), 8, rule) == 0.0)


def test_highlight_rule_refuses_nonsense():
    """SliceRule's highlight thresholds must be finite and > 0, its sprite cap a fraction in [0, 1]."""
    for bad in ({"bright": 0.0}, {"excess": math.nan}, {"dim": -1.0}, {"sprites": 2.0}, {"sprites": -0.1}):
        with pytest.raises(DofviewError):
            SliceRule(**bad)


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_over_the_cap_the_frame_does_not_follow_the_gpus_order(backend):
    """Caps that the points' highlights overrun part of the way: a layer's highlights are drawn all
    or none (counted first), so that the frame is the same draw after draw and is the CPU twin's,
    which takes the same layers (before, which sprites a cap kept followed the GPU's atomic order:
    tests/test_perf.py's hidden-Gaussian test, which draws a random cloud over the cap, differed in 1
    run of 6); and whatever the cap, no light is lost."""
    scene = _lights_before_a_wall("linear")
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 128, 96, 60.0)
    lens = Lens(1.2, 60.0)
    r = get_backend(backend, scene)
    try:
        r.slice_rule = OFF
        off = r.render(cam, lens, RenderSettings()).rgba
        r.slice_rule = None
        full = r.render(cam, lens, RenderSettings()).rgba
        kept = set()
        for cap in (3, 12, 40):
            rule = replace(SLICE_RULE, sprites=cap / (128 * 96))
            r.slice_rule = rule
            frames = [r.render(cam, lens, RenderSettings()).rgba for _ in range(3)]
            for other in frames[1:]:
                assert np.abs(other - frames[0]).max() <= 1e-6 * frames[0][..., :3].max()
            twin = render_reference_sliced(scene, cam, lens, RenderSettings(), rule=rule).rgba
            assert psnr(frames[0], twin) >= 80.0  # 91.7 dB measured at each cap (67 at 12 when the GPU's order chose)
            assert frames[0][..., :3].sum() == pytest.approx(off[..., :3].sum(), rel=2e-3)
            kept.add(round(float(np.abs(frames[0] - off).sum()), 3))
    finally:
        r.release()
    assert len(kept) >= 2 and max(kept) <= np.abs(full - off).sum() * 1.001  # the caps keep different layers
