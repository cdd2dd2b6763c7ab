"""The GL renderer against the independent CPU reference and the thin-lens accumulation."""

import numpy as np
import pytest
from conftest import assert_matches_reference, assert_matches_sliced_reference, psnr, random_scene

from dofview.camera import look_at
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering.accumulate import accumulate
from dofview.rendering.quad import QuadBackend
from dofview.rendering.reference import render_reference, render_reference_sliced
from dofview.scene import GaussianScene
from dofview.tonemap import OPERATORS, Tonemap, display, to_uint8

TAUS = [0.0, 1 / 255, 2 / 255]
CAM = look_at([0.2, -0.1, 0.0], [0.0, 0.0, 5.0], 96, 72, 60)


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
@pytest.mark.parametrize("aperture", [0.0, 30.0, 120.0])
@pytest.mark.parametrize("tau", TAUS)
@pytest.mark.parametrize("dof", ["sliced", "splat"])
def test_gl_matches_cpu_reference(backend, degree, aperture, tau, dof):
    """The renderer's math, in its float32 storage layout, against the float64 reference of each
    depth-of-field mode. (The packed layout's own error is measured against this one in
    test_packing.py.)"""
    scene = random_scene(degree=degree, seed=degree)
    settings = RenderSettings(tau=tau, dof=dof)
    lens = Lens(focus=4.5, aperture=aperture)
    gl = backend(scene, packed=False).render(CAM, lens, settings)
    if dof == "sliced":
        assert_matches_sliced_reference(gl, render_reference_sliced(scene, CAM, lens, settings))
    else:
        assert_matches_reference(gl, render_reference(scene, CAM, lens, settings, margins=True))


@pytest.mark.parametrize("norm", ["none", "energy", "optical-depth"])
@pytest.mark.parametrize("blend_linear", [False, True])
@pytest.mark.parametrize("cut", ["drop", "conserve"])
def test_gl_matches_reference_for_every_option(backend, norm, blend_linear, cut):
    scene = random_scene(seed=7, colour_space="srgb")
    settings = RenderSettings(tau=1 / 255, k=1 / 9, opacity_norm=norm, blend_linear=blend_linear, cut=cut, dof="splat")
    lens = Lens(focus=3.0, aperture=80.0)
    assert_matches_reference(backend(scene, packed=False).render(CAM, lens, settings), render_reference(scene, CAM, lens, settings, margins=True))


@pytest.mark.parametrize("tau", [0.0, 1 / 255])
@pytest.mark.parametrize("aperture", [30.0, 120.0])
@pytest.mark.parametrize("norm", ["none", "energy"])
def test_gl_matches_reference_with_the_disk_kernel(backend, tau, aperture, norm):
    """The disk kernel (RenderSettings.kernel): its profile, area-ratio opacity and τ-tight support
    in lens.glsl against the float64 twin in lens.py."""
    scene = random_scene(degree=1, seed=5)
    settings = RenderSettings(tau=tau, kernel="disk", opacity_norm=norm, dof="splat")
    lens = Lens(focus=4.5, aperture=aperture)
    gl = backend(scene, packed=False).render(CAM, lens, settings)
    assert_matches_reference(gl, render_reference(scene, CAM, lens, settings, margins=True))


@pytest.mark.parametrize("dof", ["sliced", "splat"])
def test_linear_hdr_scene_matches_reference(backend, dof):
    scene = random_scene(seed=3, colour_space="linear")
    scene.sh_dc *= 40.0  # radiance far above 1
    lens = Lens(focus=6.0, aperture=50.0)
    settings = RenderSettings(dof=dof)
    gl = backend(scene, packed=False).render(CAM, lens, settings)
    if dof == "sliced":
        ref = render_reference_sliced(scene, CAM, lens, settings)
        assert ref.rgba.max() > 10
        assert_matches_sliced_reference(gl, ref)
    else:
        ref = render_reference(scene, CAM, lens, settings, margins=True)
        assert ref[0].rgba.max() > 10
        assert_matches_reference(gl, ref)


def test_aperture_zero_is_the_pinhole_image_at_any_focus():
    scene = random_scene(seed=11)
    r = QuadBackend(scene)
    pinhole = r.render(CAM, Lens(focus=1.0, aperture=0.0))
    for focus in (0.5, 5.0, np.inf):
        again = r.render(CAM, Lens(focus=focus, aperture=0.0))
        np.testing.assert_array_equal(again.rgba, pinhole.rgba)


@pytest.mark.parametrize("dof", ["sliced", "splat"])
def test_focus_plane_stays_sharp_and_blur_grows_away_from_it(dof):
    """Two small Gaussians at z = 3 and z = 6; focusing on one keeps it (nearly) as in the pinhole."""
    scene = GaussianScene(means=[[-0.6, 0, 3.0], [1.7, 0, 6.0]], quats=[[1, 0, 0, 0]] * 2,
                          scales=[[0.01] * 3] * 2, opacities=[0.9, 0.9], sh_dc=[[1, 1, 1]] * 2)
    r = QuadBackend(scene)
    cam = look_at([0, 0, 0], [0, 0, 1], 128, 64, 60)
    pin = r.render(cam, Lens(3.0, 0.0), RenderSettings(tau=0, dof=dof)).alpha
    near_focus = r.render(cam, Lens(3.0, 200.0), RenderSettings(tau=0, dof=dof)).alpha
    # the far one's disk (17 px about x = 95), blurred at 1/8 resolution in the sliced mode, reaches x ≈ 62
    left, right = slice(0, 48), slice(64, 128)
    np.testing.assert_allclose(near_focus[:, left], pin[:, left], atol=1e-6)
    # the far one spreads: its peak drops and its footprint widens
    assert near_focus[:, right].max() < 0.5 * pin[:, right].max()
    assert (near_focus[:, right] > 1e-3).sum() > 4 * (pin[:, right] > 1e-3).sum()


def test_single_gaussian_blur_matches_thin_lens_second_moment():
    """A small Gaussian off the focus plane: second moment of the single-pass blur vs 256-sample
    accumulation of pinhole renders, within 5% (τ = 0 so that no faint tail is cut)."""
    scene = GaussianScene(means=[[0.0, 0.0, 2.0]], quats=[[1, 0, 0, 0]], scales=[[0.01] * 3],
                          opacities=[0.3], sh_dc=[[1, 1, 1]])
    cam = look_at([0, 0, 0], [0, 0, 1], 97, 97, 60)
    r = QuadBackend(scene)
    settings = RenderSettings(tau=0.0, dof="splat")
    lens = Lens(focus=4.0, aperture=64.0)  # R = ½·64·|1/2 − 1/4| = 8 px
    single = r.render(cam, lens, settings).alpha
    acc = accumulate(lambda c: r.render(c, Lens(lens.focus, 0.0), settings), cam, lens, samples=256).alpha

    def moments(img):
        y, x = np.mgrid[: img.shape[0], : img.shape[1]] + 0.5
        m = img.sum()
        mx, my = (img * x).sum() / m, (img * y).sum() / m
        return m, (img * (x - mx) ** 2).sum() / m, (img * (y - my) ** 2).sum() / m

    m1, vx1, vy1 = moments(single)
    m2, vx2, vy2 = moments(acc)
    assert vx2 > 10  # the reference really is blurred (pinhole variance ≈ 0.4 px²)
    assert vx1 == pytest.approx(vx2, rel=0.05)
    assert vy1 == pytest.approx(vy2, rel=0.05)
    assert m1 == pytest.approx(m2, rel=0.02)  # energy-preserving opacity keeps the total


@pytest.mark.parametrize("operator", list(OPERATORS))
@pytest.mark.parametrize("colour_space", ["srgb", "linear"])
def test_gpu_tonemap_matches_numpy(operator, colour_space):
    """Every operator's GLSL pass against its numpy twin (≥ 45 dB, clip within one 8-bit step),
    with the statistics from the read-back frame; and the GPU statistics equal the CPU ones."""
    from dofview.tonemap.stats import frame_stats

    scene = random_scene(seed=5, colour_space=colour_space)
    r = QuadBackend(scene)
    op = OPERATORS[operator]()
    for tm in (Tonemap(operator=op), Tonemap(exposure=2.0, gamma=2.2, background=(0.2, 0.5, 1.0), operator=op),
               Tonemap(exposure=-1.75, gamma=1.0, operator=op)):
        frame = r.render(CAM, Lens(4.0, 40.0))
        stats = frame_stats(frame.rgba, op, colour_space == "srgb") if op.adaptive else None
        if op.adaptive:
            np.testing.assert_allclose(r.frame_stats(op).scalars(), stats.scalars(), atol=1e-3)
        gpu = r.display_image(tm, stats=stats).astype(int)
        cpu = to_uint8(display(frame.rgba, frame.encoded, tm, stats, frame.depth)).astype(int)
        assert psnr(gpu / 255.0, cpu / 255.0) >= 45.0
        if operator == "clip":
            assert np.abs(gpu - cpu).max() <= 1


def test_srgb_scene_at_zero_ev_reproduces_the_blend():
    """Exposure is applied in linear light: at 0 EV and γ = 2.2 an sRGB scene shows its trained
    (display-encoded) blend unchanged — gamma is not applied twice."""
    scene = random_scene(seed=6)
    r = QuadBackend(scene)
    r.draw(CAM, Lens(4.0, 0.0))
    blended = np.frombuffer(r.colour_tex.read(), np.float32).reshape(72, 96, 4)[::-1, :, :3]
    np.testing.assert_allclose(r.display_image(Tonemap()).astype(int), to_uint8(blended).astype(int), atol=1)


def test_lens_change_does_not_resort(monkeypatch):
    scene = random_scene(seed=2)
    r = QuadBackend(scene)
    calls = []
    import dofview.rendering.quad as mod

    real = mod.front_to_back
    monkeypatch.setattr(mod, "front_to_back", lambda m, c: calls.append(1) or real(m, c))
    r.render(CAM, Lens(4.0, 0.0))
    r.render(CAM, Lens(2.0, 90.0), RenderSettings(tau=0.0))
    assert len(calls) == 1
    r.render(look_at([0.3, 0, 0], [0, 0, 5], 96, 72, 60), Lens(2.0, 90.0))
    assert len(calls) == 2


def test_culling_counts_and_tau_culls_faint_blurred_gaussians():
    scene = random_scene(seed=4)
    r = QuadBackend(scene)
    r.draw(CAM, Lens(4.5, 0.0), RenderSettings(tau=0.0, dof="splat"), count=True)
    all_drawn = r.stats.drawn
    assert 0 < all_drawn <= scene.count
    r.draw(CAM, Lens(4.5, 0.0), RenderSettings(tau=0.0), count=True)
    assert r.stats.drawn == all_drawn  # the sliced mode draws each Gaussian once
    r.draw(CAM, Lens(4.5, 400.0), RenderSettings(tau=2 / 255, cut="drop", dof="splat"), count=True)
    assert r.stats.drawn < all_drawn  # blurred o·β fell below τ: those are never drawn
    r.draw(CAM, Lens(4.5, 400.0), RenderSettings(tau=2 / 255, cut="conserve", dof="splat"), count=True)
    assert r.stats.drawn >= all_drawn  # conserving the mass, faint splats shrink instead (blur may bring more on screen)


def test_degree0_scene_has_no_sh_buffer_and_degree3_fits_128_bytes():
    r0 = QuadBackend(random_scene(degree=0))
    r3 = QuadBackend(random_scene(degree=3))
    assert 2 not in r0._buffers
    assert r0.bytes_per_gaussian == 32 + 4  # core + draw order
    assert r3._buffers[2].size == r3.scene.count * 15 * 3 * 2
    assert r3.bytes_per_gaussian <= 128
    full = QuadBackend(random_scene(degree=3), packed=False)
    assert full.bytes_per_gaussian == 14 * 4 + 45 * 4 + 4
