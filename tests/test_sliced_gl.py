"""Sliced depth of field on the GPU (rendering/sliced.py, ``--dof sliced``): both backends against
the CPU reference of the mode, the pinhole at A = 0, a slanted floor, the bladed aperture, the
settings' round trip and the CLI path."""

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from dofview.bench.metrics import psnr
from dofview.bench.primitives import Parts, add_panel
from dofview.camera import look_at
from dofview.cli import main
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.io import load_scene
from dofview.io.exr import read_exr
from dofview.lens import Lens, aperture_for_blur
from dofview.rendering import get_backend
from dofview.rendering.depth_order import camera_depths
from dofview.rendering.reference import render_reference_sliced
from dofview.rendering.sliced import MAX_FULL_RADIUS, plan_layers

ROOT = Path(__file__).resolve().parents[1]
CARDS = ROOT / "samples" / "cards.ply"
TWO_PLANES = ROOT / "tests" / "data" / "two_planes.ply"
SLICED = RenderSettings(dof="sliced")
MIN_PSNR = 40.0  # GL float32 against the float64 reference; measured ≥ 80 dB on cards at 160×120


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


@pytest.mark.parametrize("backend", ["quad", "compute"])
@pytest.mark.parametrize("path", [CARDS, TWO_PLANES], ids=["cards", "two_planes"])
def test_sliced_matches_the_cpu_reference(backend, path):
    scene = load_scene(path, progress=False)
    cam, lens = _view(scene, 16.0)
    r = get_backend(backend, scene)
    try:
        gl = r.render(cam, lens, SLICED)
        layers = r._sliced.layers
    finally:
        r.release()
    ref = render_reference_sliced(scene, cam, lens, SLICED)
    assert len(layers) >= 8 and max(l.radius for l in layers) > 2 * MAX_FULL_RADIUS  # full and reduced resolution
    assert ref.alpha.mean() > 0.1
    assert psnr(gl.rgba, ref.rgba) >= MIN_PSNR
    both = (gl.alpha > 0.5) & (ref.alpha > 0.5)
    close = np.abs(gl.depth[both] - ref.depth[both]) <= 1e-3 * ref.depth[both]
    assert close.mean() > 0.99  # the rest: pixels at a splat's 3σ cut, where float32 may decide otherwise


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_at_aperture_zero_sliced_is_the_pinhole(backend):
    scene = load_scene(CARDS, progress=False)
    cam, lens = _view(scene, 16.0)
    pin_lens = Lens(lens.focus, 0.0)
    r = get_backend(backend, scene)
    try:
        pin = r.render(cam, pin_lens, RenderSettings(tau=0.0))
        sliced = r.render(cam, pin_lens, SLICED)
        assert len(r._sliced.layers) == 1 and r._sliced.layers[0].radius == 0.0
        # a real lens's slices, none blurred (radius < ½ px everywhere at a tiny aperture)
        tiny = r.render(cam, replace(lens, aperture=lens.aperture * 1e-3), SLICED)
    finally:
        r.release()
    assert psnr(sliced.rgba, pin.rgba) >= 60.0
    assert np.allclose(sliced.depth, pin.depth, rtol=1e-5, atol=1e-6)
    assert psnr(tiny.rgba, pin.rgba) >= 60.0


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_shared_layers_count_each_gaussian_once(backend):
    """The grey blend of a shared layer prepares the backend twice more: the Gaussians drawn are
    still counted as the disjoint slices count them."""
    scene = load_scene(CARDS, progress=False)
    cam, lens = _view(scene, 16.0)
    r = get_backend(backend, scene)
    try:
        drawn = []
        for share in (True, False):
            r.draw(cam, lens, SLICED, count=True)
            assert share == any(l.back_radius is not None for l in r._sliced.layers)
            drawn.append(r.stats.drawn)
            r._sliced.share = False
    finally:
        r.release()
    assert drawn[0] == drawn[1] > 0


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


def test_layers_are_contiguous_ranges_and_huge_coc_splats_are_set_aside():
    z = np.array([-1.0, 0.005, 0.02, 0.5, 1.0, 1.0, 2.0, 50.0], np.float32)  # draw order, nearest first
    lens = Lens(1.0, 20.0)
    for share in (False, True):
        layers, t = plan_layers(z, lens, near=0.01, share=share)
        assert layers[0].first == 2  # the two culled ones are left out
        assert layers[0].lensed and layers[0].end == 3  # c(0.02) = 490 px > huge: per-splat front layer
        assert [(l.first, l.end) for l in layers[1:]] == [(3, 4), (4, 6), (6, 7), (7, 8)]
        assert not any(l.lensed for l in layers[1:])
        assert share == any(l.back_radius is not None for l in layers)
        stale, _ = plan_layers(np.array([0.5, 2.0, 1.0, 50.0], np.float32), lens, near=0.01, share=share)
        assert [l.first for l in stale] == sorted(l.first for l in stale) and stale[-1].end == 4  # an earlier view's order
    disjoint, _ = plan_layers(z, lens, near=0.01, share=False)
    assert disjoint[2].radius == 0.0 and disjoint[1].radius > disjoint[3].radius > 0  # c(0.5) = 10 px, c(2) = −5 px
    # shared: each splat between its two nearest centres, its share of the farther linear in its CoC
    assert layers[2].radius > 0.5 and layers[2].back_radius == 0.0 and np.all(t[4:6] == 1.0)  # c(1) = 0: the focus centre
    near_r, far_r = layers[1].radius, layers[1].back_radius  # centres at ±r px of CoC around c(0.5) = 10 px
    assert near_r > 10.0 > far_r and t[3] == pytest.approx((near_r - 10.0) / (near_r - far_r), abs=1e-6)
    assert layers[-1].back_radius is None  # behind the last centre: wholly its own


def test_slanted_floor_follows_the_cpu_twin():
    """A uniform grey floor from z = 0.5 to 9 crosses many slices: the GL path shows the numpy
    twin's profile down the floor, adding no banding of its own (reduced-resolution levels, guard
    band, screen boxes), and with neighbour sharing (the default) it is seamless, as
    tests/test_slices.py asserts for the numpy twin: as opaque as the pinhole, and its second
    difference down the floor well under the disjoint slices'."""
    parts = Parts.empty()
    add_panel(parts, 1, 0.6, {0: (-4.0, 4.0), 2: (0.5, 9.0)}, (0.6, 0.6, 0.6), spacing=0.05, opacity=0.98)
    scene = parts.build("srgb", "floor")
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.35, 4.0), 160, 120, 60.0)
    lens = Lens(3.0, aperture_for_blur(10.0, 3.0, 1.0, 9.0))
    r = get_backend("quad", scene)
    try:
        gl = r.render(cam, lens, SLICED)
        assert len(r._sliced.layers) >= 10 and any(l.back_radius is not None for l in r._sliced.layers)
        r._sliced.share = False
        disjoint = r.render(cam, lens, SLICED)
        pin = r.render(cam, Lens(3.0, 0.0), RenderSettings(tau=0.0))
    finally:
        r.release()
    ref = render_reference_sliced(scene, cam, lens, SLICED)
    ref_disjoint = render_reference_sliced(scene, cam, lens, SLICED, share=False)
    rows = np.nonzero(pin.alpha[:, 80] > 0.95)[0]
    rows = rows[rows > rows.min() + 15]
    cols = slice(50, 110)
    assert rows.size > 20

    def profile(frame):
        """Coverage against the pinhole's and luminance, per floor row; the largest |second difference|."""
        a = frame.alpha[rows, cols].mean(axis=1) - pin.alpha[rows, cols].mean(axis=1)
        lum = frame.rgba[rows, cols, :3].mean(axis=(1, 2))
        return a, lum, np.abs(np.diff(lum, 2)).max()

    (gl_a, gl_lum, gl_d2), (ref_a, ref_lum, ref_d2) = profile(gl), profile(ref)
    (dis_a, dis_lum, dis_d2), (_, ref_dis_lum, ref_dis_d2) = profile(disjoint), profile(ref_disjoint)
    for lum, ref_l, d2, ref_d in ((gl_lum, ref_lum, gl_d2, ref_d2), (dis_lum, ref_dis_lum, dis_d2, ref_dis_d2)):
        assert np.max(np.abs(lum - ref_l)) < 2e-3
        assert d2 <= ref_d + 1e-3
    assert np.min(dis_a) < -0.05  # disjoint slices let the black through at their cuts…
    # …the default keeps the floor as opaque as the pinhole; its last 8 rows are left out: there the
    # frame's bottom border meets the nearest floor's blurs at reduced resolution, whose edge
    # blocks lose up to 0.09 of coverage in the numpy twin too at the same resolutions (0.03 at full)
    inner = rows < gl.alpha.shape[0] - 8
    assert np.all(np.abs(gl_a[inner]) < 0.05)
    assert gl_d2 < 0.6 * dis_d2


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_bladed_aperture_blurs_a_point_into_the_polygon(backend):
    """One small bright splat far behind focus: its bokeh is the aperture, a hexagon whose corner
    points along the rotation, matching the CPU reference."""
    parts = Parts.empty()
    parts.add(np.array([[0.0, 0.0, 6.0]]), 0.004, np.array([[1.0, 1.0, 1.0]]), 0.99)
    scene = parts.build("srgb", "point")
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 96, 96, 40.0)
    lens = Lens(1.0, 2 * 20.0 / (1 - 1 / 6.0))  # a 20 px CoC at z = 6: blurred at reduced resolution
    hexagon = RenderSettings(dof="sliced", blades=6, blade_rotation=0.0)
    r = get_backend(backend, scene)
    try:
        disk = r.render(cam, lens, SLICED).alpha
        hexa = r.render(cam, lens, hexagon).alpha
    finally:
        r.release()
    ref = render_reference_sliced(scene, cam, lens, hexagon).alpha
    assert psnr(hexa, ref) >= MIN_PSNR
    ys, xs = np.mgrid[:96, :96]
    cy, cx = (int(round(float((g * disk).sum() / disk.sum()))) for g in (ys, xs))

    def reach(img: np.ndarray, axis: int) -> int:
        """Pixels from the centre to the bokeh's edge (half its peak) along +x (1) or image down (0)."""
        line = img[cy, cx:] if axis == 1 else img[cy:, cx]
        return int(np.nonzero(line > 0.5 * img.max())[0].max())

    # the hexagon's corner at +x reaches the disk's radius, its flat side at +y only the apothem (cos 30°)
    assert abs(reach(hexa, 1) - reach(disk, 1)) <= 1
    assert reach(hexa, 0) <= round(0.9 * reach(disk, 0)) and reach(disk, 0) >= 15


def test_settings_round_trip_and_refuse_nonsense():
    s = RenderSettings(dof="sliced", blades=7, blade_rotation=12.5)
    assert RenderSettings.from_dict(json.loads(json.dumps(s.to_dict()))) == s
    assert "--dof" in s.to_args() and "--blades" in s.to_args()
    for bad in ({"dof": "layered"}, {"blades": 2}, {"blade_rotation": float("nan")}):
        with pytest.raises(DofviewError):
            RenderSettings(**bad)


def test_cli_renders_sliced_and_records_it(tmp_path):
    exr = tmp_path / "s.exr"
    assert main(["render", str(CARDS), "--cameras", str(ROOT / "samples" / "cards_cameras.json"), "--width", "96",
                 "--height", "72", "--blur", "10", "--dof", "sliced", "--blades", "5", "-o", str(exr)]) == 0
    channels, header = read_exr(exr)
    render = json.loads(header["dofview:render"])
    assert render["dof"] == "sliced" and render["blades"] == 5
    assert channels["A"].mean() > 0.1 and np.isfinite(channels["Z"]).all()
    with pytest.raises(SystemExit) as bad:
        main(["render", str(CARDS), "--dof", "blur", "-o", str(tmp_path / "x.exr")])
    assert bad.value.code == 2
    assert not (tmp_path / "x.exr").exists()
