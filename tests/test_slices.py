"""Depth-sliced depth of field (rendering/slices.py): the slicing rule, the aperture kernel, the
blur's guard band, and the composite against the GL renderer's own pinhole blend."""

import math
from pathlib import Path

import numpy as np
import pytest

from dofview.bench.metrics import psnr
from dofview.bench.primitives import Parts, add_panel
from dofview.bench.sliced_study import ANCHOR, COMPOSITE_VARIANTS, DEFAULT_COMPOSITE, render_slices, sliced_frame
from dofview.bench.variants import make_references
from dofview.camera import look_at
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.io import load_scene
from dofview.io.cameras import load_cameras_json
from dofview.lens import Lens, aperture_for_blur
from dofview.rendering import get_backend
from dofview.rendering.slices import (
    COMPOSITES,
    SliceRule,
    aperture_kernel,
    assign_slices,
    blur_slice,
    share_weights,
    signed_coc,
    slice_edges,
    sliced_image,
)
from dofview.rendering.depth_order import camera_depths
from dofview.tonemap import encode

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
PINHOLE = RenderSettings(tau=0.0)
SHARE, DEFAULT = COMPOSITE_VARIANTS[DEFAULT_COMPOSITE]  # the chosen rule: neighbour sharing + its composite


def _unblurred(sf, **kw):
    """The composite of ``sf`` with every radius (both of a shared layer's) set to zero."""
    splits = [None if sp is None else (sp[0], 0.0) for sp in sf.splits]
    return sliced_image(sf.layers, [0.0] * len(sf.layers), sf.encoded, centres=sf.centres, splits=splits, **kw)


# ---- the slicing rule -------------------------------------------------------------------------------
def test_slice_edges_grow_from_a_focus_slice_and_cover_the_range():
    rule = SliceRule(width=2.0, growth=1.25, huge=math.inf)
    e = slice_edges(-30.0, 12.0, rule)
    assert np.all(np.diff(e) < 0)  # descending: front to back
    widths = -np.diff(e)
    k = int(np.argmin(np.abs(e[:-1] + e[1:])))  # the slice centred on c = 0
    assert e[k] == 1.0 and e[k + 1] == -1.0
    np.testing.assert_allclose(widths[k + 1:] / widths[k:-1], 1.25)  # behind focus
    np.testing.assert_allclose(widths[:k] / widths[1:k + 1], 1.25)  # in front of focus
    assert e[0] >= 12.0 and e[-1] <= -30.0


def test_assign_slices_puts_each_splat_between_its_edges_and_huge_ones_aside():
    rng = np.random.default_rng(1)
    c = np.concatenate([rng.uniform(-50, 50, 500), [200.0, -300.0, 0.0]])
    s = assign_slices(c, SliceRule(1.0, 1.15, 40.0))
    inside = (s.index >= 0) & (s.index < s.count)
    i = s.index[inside]
    assert np.all(s.edges[i] >= c[inside]) and np.all(c[inside] > s.edges[i + 1])
    assert set(s.index[c > 40]) == {-1} and set(s.index[c < -40]) == {s.count}
    np.testing.assert_allclose(s.radius, np.abs(s.edges[:-1] + s.edges[1:]) / 2)
    assert s.radius[s.index[-1]] == 0.0  # the focus slice is not blurred


def test_signed_coc_is_positive_in_front_of_focus():
    c = signed_coc(np.array([1.0, 2.0, 4.0]), Lens(2.0, 10.0))
    np.testing.assert_allclose(c, [2.5, 0.0, -1.25])


def test_share_weights_split_each_splat_between_its_two_centres_linearly():
    centres = np.array([6.0, 2.0, 0.0, -2.0])
    c = np.array([9.0, 6.0, 4.0, 3.0, 1.0, 0.0, -1.5, -2.0, -7.0])
    interval, t = share_weights(c, centres)
    np.testing.assert_array_equal(interval, [0, 0, 1, 1, 2, 2, 3, 3, 4])
    np.testing.assert_allclose(t, [0.0, 0.0, 0.5, 0.75, 0.5, 1.0, 0.75, 1.0, 1.0])
    # a splat's blur radius, interpolated between its two centres, follows |c| within the slices
    radius = np.abs((1 - t) * centres[np.maximum(interval - 1, 0)] + t * centres[np.minimum(interval, 3)])
    inside = (c <= centres[0]) & (c >= centres[-1])
    np.testing.assert_allclose(radius[inside], np.abs(c[inside]))


def test_rule_refuses_nonsense():
    for kw in ({"width": 0.0}, {"growth": 0.9}, {"huge": 0.1}):
        with pytest.raises(DofviewError):
            SliceRule(**kw)


# ---- the aperture kernel ----------------------------------------------------------------------------
def test_disk_kernel_profile():
    r = 5.3
    k = aperture_kernel(r)
    assert k.sum() == pytest.approx(1.0)
    np.testing.assert_array_equal(k, k[::-1])
    np.testing.assert_array_equal(k, k[:, ::-1])
    np.testing.assert_allclose(k, k.T, atol=1e-15)
    n = k.shape[0] // 2
    y, x = np.mgrid[-n:n + 1, -n:n + 1]
    d = np.hypot(x, y)
    assert np.all(k[d >= r + 0.5] == 0)
    assert np.all(k[d <= r - 0.5] == k.max())  # flat inside: a disk, not a Gaussian
    edge = k[(d > r - 0.5) & (d < r + 0.5)]
    assert np.all((edge > 0) & (edge < k.max()))  # anti-aliased rim
    assert (k / k.max()).sum() == pytest.approx(math.pi * r * r, rel=0.01)  # the disk's area
    small = aperture_kernel(0.3)  # below half a pixel: no blur
    assert small[small.shape[0] // 2, small.shape[1] // 2] == 1.0 and small.sum() == 1.0


def test_bladed_kernel_is_the_polygon():
    r = 8.0
    hexagon = aperture_kernel(r, blades=6)
    n = hexagon.shape[0] // 2
    assert (hexagon / hexagon.max()).sum() == pytest.approx(1.5 * math.sqrt(3) * r * r, rel=0.02)
    assert hexagon[n, n + 8] > 0  # a corner on the circle (rotation 0: along +x)
    assert hexagon[n + 8, n] == 0  # the middle of an edge is inside the circle: r·cos 30° ≈ 6.9
    np.testing.assert_allclose(aperture_kernel(r, 6, math.pi / 3), hexagon, atol=1e-12)  # its symmetry
    assert not np.allclose(aperture_kernel(r, 6, math.pi / 6), hexagon)
    with pytest.raises(DofviewError):
        aperture_kernel(r, blades=2)


def test_guard_band_keeps_coverage_at_the_frame_border():
    full = np.ones((30, 40, 4))
    kept = blur_slice(full, 6.0, "replicate")
    lost = blur_slice(full, 6.0, "zero")
    np.testing.assert_allclose(kept, 1.0, atol=1e-9)
    assert lost[0, 20, 3] < 0.7 and lost[15, 20, 3] == pytest.approx(1.0)
    dot = np.zeros((31, 31, 4))
    dot[15, 15] = 1.0
    k = aperture_kernel(5.0)  # 13 × 13: a point spreads into the kernel itself
    np.testing.assert_allclose(blur_slice(dot, 5.0)[15 - 6:15 + 7, 15 - 6:15 + 7, 3], k, atol=1e-12)
    np.testing.assert_allclose(blur_slice(dot, 12.0, scale=2)[..., 3].sum(), 1.0, rtol=1e-6)  # reduced res keeps mass


# ---- against the renderer's own blend ----------------------------------------------------------------
@pytest.fixture(scope="module")
def cards():
    scene = load_scene(SAMPLES / "cards.ply", progress=False)
    cam = load_cameras_json(SAMPLES / "cards_cameras.json")[0].resized(160, 120)
    r = get_backend("quad", scene)
    yield r, cam
    r.release()


def _lens(renderer, cam, blur):
    z = camera_depths(renderer.scene.means, cam)
    z = z[z > 0.01]
    focus = float(np.median(z))
    return Lens(focus, aperture_for_blur(blur, focus, float(np.percentile(z, 5)), float(np.percentile(z, 95))))


def test_at_aperture_zero_the_slices_are_the_pinhole(cards):
    r, cam = cards
    lens = _lens(r, cam, 12.0)
    pin = r.render(cam, Lens(lens.focus, 0.0), PINHOLE)
    for share in (False, True):
        sf = render_slices(r, cam, Lens(lens.focus, 0.0), SliceRule(), share=share)
        assert len(sf.layers) == 1 and sf.radii == [0.0]
        for _, kw in COMPOSITE_VARIANTS.values():
            assert psnr(sliced_frame(sf, **kw).rgba, pin.rgba) >= 60.0
        # the slices of a real lens, left unblurred, composite to the pinhole too (sharing splits a
        # layer's content between two radii, never its blend)
        sf = render_slices(r, cam, lens, SliceRule(), share=share)
        assert len(sf.layers) >= 8
        assert share == any(sp is not None for sp in sf.splits)
        for mode in COMPOSITES:
            assert psnr(_unblurred(sf, mode=mode), pin.rgba) >= 60.0
        assert psnr(_unblurred(sf, window=4.0), pin.rgba) >= 60.0
    # …in the encoded space only: composited in linear light they are not the pinhole
    assert psnr(sliced_image(sf.layers, [0.0] * len(sf.layers), False), pin.rgba) < 50.0


def test_two_slices_over_each_other_are_the_pinhole_blend_of_both(cards):
    r, cam = cards
    scene = r.scene
    z = camera_depths(scene.means, cam)
    near = z < np.median(z)
    layers = []
    for part in (near, ~near):
        sub = get_backend("quad", scene.subset(part), ctx=r.ctx)
        layers.append(sub.render(cam, Lens(1.0, 0.0), PINHOLE).rgba)
        sub.release()
    pin = r.render(cam, Lens(1.0, 0.0), PINHOLE)
    both = (layers[0][..., 3] > 0.2) & (layers[1][..., 3] > 0.2)
    assert both.mean() > 0.05  # the two layers overlap on screen
    assert psnr(sliced_image(layers, [0.0, 0.0], True), pin.rgba) >= 60.0


def test_slanted_floor_crossing_many_slices_shows_no_banding():
    """A uniform grey floor receding from z = 1 to 9 crosses 13 slices. Composited "over" from
    disjoint slices, each slice's blurred band thins where the next begins and the black shows
    through in bands; the chosen rule (neighbour sharing, so the blur follows the CoC without
    steps, and a composite that adds the complementary parts of one surface) keeps it whole."""
    parts = Parts.empty()
    add_panel(parts, 1, 0.6, {0: (-4.0, 4.0), 2: (0.5, 9.0)}, (0.6, 0.6, 0.6), spacing=0.05, opacity=0.98)
    scene = parts.build("srgb", "floor")
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.35, 4.0), 160, 120, 60.0)
    r = get_backend("quad", scene)
    try:
        lens = Lens(3.0, aperture_for_blur(10.0, 3.0, 1.0, 9.0))
        seamy = render_slices(r, cam, lens, SliceRule(), share=False)
        chosen = render_slices(r, cam, lens, SliceRule(), share=SHARE)
        pin = r.render(cam, Lens(3.0, 0.0), PINHOLE)
    finally:
        r.release()
    assert len(chosen.layers) >= 10
    assert psnr(_unblurred(chosen, **DEFAULT), pin.rgba) >= 60.0
    rows = np.nonzero(pin.alpha[:, 80] > 0.95)[0]
    rows = rows[rows > rows.min() + 15]  # the floor, away from its far edge
    assert rows.size > 20
    cols = slice(50, 110)

    def profile(frame):
        a = frame.alpha[rows, cols].mean(axis=1) - pin.alpha[rows, cols].mean(axis=1)
        lum = frame.rgba[rows, cols, :3].mean(axis=(1, 2))
        return a, np.abs(np.diff(lum, 2)).max()

    chosen_a, chosen_d2 = profile(sliced_frame(chosen, **DEFAULT))
    seamy_a, seamy_d2 = profile(sliced_frame(seamy))
    assert np.min(seamy_a) < -0.1  # disjoint slices "over" each other let the black through…
    assert np.all(np.abs(chosen_a) < 0.05)  # …the chosen rule keeps the floor as opaque as the pinhole
    assert chosen_d2 < 0.6 * seamy_d2


def test_a_frame_filling_near_wall_keeps_its_blurred_coverage():
    """A beige wall 0.5 units from the lens fills the 80 × 60 frame but for a central opening onto
    a blue plane in focus at 3; the wall's CoC is 20 px (60 px at 240 px wide). The thin lens
    blurs the opening's rim and keeps the wall opaque at the frame border; the slices must agree
    with a 48-sample accumulation of the lens on the wall's coverage (read from the red channel
    of the blend, 0.3 on the plane, 0.8 on the wall), where per-splat DoF leaves holes."""
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
        sliced = sliced_frame(render_slices(r, cam, lens, SliceRule(), share=SHARE), max_full_radius=8.0, **DEFAULT)
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
