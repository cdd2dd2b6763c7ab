"""Numerical hard cases (issue 5): degenerate Gaussians, extreme lenses, HDR, depth range, sizes.

Every output is checked for NaN/inf, and against what it should equal: the float64 CPU reference
(assert_matches_reference: PSNR ≥ 45 dB, depth within 1e-3), the pinhole image (bit-equal), or a
stated limit.
"""

import math

import numpy as np
import pytest
from conftest import assert_matches_reference, assert_matches_sliced_reference, psnr, random_scene

from dofview.camera import look_at
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.io.exr import HALF_MAX, read_exr
from dofview.io.ply import read_ply, scene_rows, write_ply
from dofview.io.png import read_png
from dofview.lens import Lens, PhysicalLens
from dofview.rendering.quad import QuadBackend
from dofview.rendering.reference import project, render_reference, render_reference_sliced
from dofview.scene import SH_C0, GaussianScene

CAM = look_at([0, 0, 0], [0, 0, 5], 64, 48, 60)


def scene_of(means, scales, quats=None, opacities=0.8, seed=0) -> GaussianScene:
    means = np.asarray(means, np.float64).reshape(-1, 3)
    n = len(means)
    rng = np.random.default_rng(seed)
    return GaussianScene(means=means, quats=np.tile([1.0, 0, 0, 0], (n, 1)) if quats is None else quats,
                         scales=np.broadcast_to(scales, (n, 3)), opacities=np.broadcast_to(opacities, (n,)),
                         sh_dc=rng.normal(size=(n, 3)))


def cloud(n=200, seed=1):
    """(n, 3) means in front of CAM around z = 5, and (n, 4) random quaternions."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-1, 1, (n, 3)) * [1.5, 1.0, 1.0] + [0, 0, 5], rng.normal(size=(n, 4))


def check(scene, lens=Lens(4.0, 0.0), settings=RenderSettings(), cam=CAM, packed=False):
    """GL in float32 storage against the float64 reference (images with little coverage, where the
    depth check has nothing to hold, by PSNR ≥ 45 dB alone); with ``packed`` also the packed layout
    against float32 storage at the packing's own bar (PSNR ≥ 50 dB, test_packing.py). Returns the
    GL frame in the layout asked for."""
    gl = QuadBackend(scene, packed=False).render(cam, lens, settings)
    if settings.dof == "sliced":
        ref = render_reference_sliced(scene, cam, lens, settings)
        if ref.alpha.max() > 0.5:
            assert_matches_sliced_reference(gl, ref)
        else:
            assert np.isfinite(gl.rgba).all() and np.isfinite(gl.depth).all()
            assert psnr(gl.rgba, ref.rgba, max(float(ref.rgba.max()), 1.0)) >= 45.0
    else:
        ref = render_reference(scene, cam, lens, settings, margins=True)
        if ref[0].alpha.max() > 0.5:
            assert_matches_reference(gl, ref)
        else:
            assert np.isfinite(gl.rgba).all() and np.isfinite(gl.depth).all()
            assert psnr(gl.rgba, ref[0].rgba, max(float(ref[0].rgba.max()), 1.0)) >= 45.0
    if not packed:
        return gl
    small = QuadBackend(scene, packed=True).render(cam, lens, settings)
    assert np.isfinite(small.rgba).all() and np.isfinite(small.depth).all()
    assert psnr(small.rgba, gl.rgba, max(float(gl.rgba.max()), 1.0)) >= 50.0
    return small


def assert_finite_and_empty(frame):
    assert np.isfinite(frame.rgba).all() and np.isfinite(frame.depth).all()
    assert not frame.rgba.any() and not frame.depth.any()


# ---- near plane and the camera inside a Gaussian --------------------------------------------------
@pytest.mark.parametrize("tau", [0.0, 2 / 255])
def test_gaussians_at_straddling_and_behind_the_near_plane(tau):
    """near = 0.0625 (exact in float32, so 'at the plane' is the same decision in both renderers):
    means exactly on it and behind it are culled, those just in front straddle it with their
    support and are drawn; a far layer keeps the image covered."""
    rng = np.random.default_rng(3)
    near = 0.0625
    xy = rng.uniform(-0.04, 0.04, (60, 2))
    z = np.repeat([near, near - 0.01, -0.5, near + 0.01, near + 0.03], 12)
    front = np.c_[xy, z]
    far, _ = cloud(150, seed=4)
    scene = scene_of(np.r_[front, far], np.r_[np.full((60, 3), 0.02), np.full((150, 3), 0.15)], seed=3)
    settings = RenderSettings(tau=tau, near=near)
    gl = check(scene, Lens(2.0, 40.0), settings)
    r = QuadBackend(scene)
    r.draw(CAM, Lens(2.0, 0.0), settings, count=True)
    assert r.stats.drawn <= scene.count - 36  # the 36 at or behind the plane are never drawn
    assert gl.alpha.max() > 0.9


def test_camera_inside_a_gaussian():
    """The camera sits inside a large Gaussian's 1σ ellipsoid (mean in front) and exactly on the
    mean of another (culled): the image stays finite and equals the reference."""
    far, q = cloud(100)
    means = np.r_[[[0.0, 0.0, 0.3], [0.0, 0.0, 0.0]], far]
    scales = np.r_[[[2.0, 2.0, 2.0], [1.0, 1.0, 1.0]], np.full((100, 3), 0.1)]
    scene = scene_of(means, scales, np.r_[[[1, 0, 0, 0]] * 2, q], opacities=0.6)
    for lens in (Lens(4.0, 0.0), Lens(0.5, 60.0)):
        gl = check(scene, lens)
        assert gl.alpha.min() > 0.3  # the big one covers every pixel


# ---- degenerate Gaussians ---------------------------------------------------------------------------
@pytest.mark.parametrize("packed", [False, True])
@pytest.mark.parametrize("aperture", [0.0, 80.0])
def test_scales_from_1e_minus_8_to_1e4(packed, aperture):
    """det Σ₂ → 0 and β → 0 for the tiny ones (the 0.3 px² low-pass keeps them finite), screen-filling
    ones from the huge ones; per-axis scales drawn log-uniformly over 12 decades."""
    means, q = cloud(300, seed=5)
    rng = np.random.default_rng(5)
    scales = np.exp(rng.uniform(math.log(1e-8), math.log(1e4), (300, 3)))
    scene = scene_of(means, scales, q, opacities=rng.uniform(0.05, 1.0, 300))
    check(scene, Lens(3.0, aperture), RenderSettings(tau=1 / 255), packed=packed)


@pytest.mark.parametrize("aperture", [0.0, 60.0])
def test_needle_like_gaussians(aperture):
    """Axis ratios of 1e6 in random orientations: det Σ₂ = |p₀ × p₁|² never cancels."""
    means, q = cloud(200, seed=6)
    rng = np.random.default_rng(6)
    scales = np.array([1e-6, 1e-6, 1.0]) * rng.uniform(0.1, 1.0, (200, 1))
    check(scene_of(means, scales, q, opacities=0.9), Lens(3.0, aperture))


@pytest.mark.parametrize("packed", [False, True])
def test_zero_and_denormal_quaternions_are_the_identity(packed):
    means, _ = cloud(100, seed=7)
    quats = np.zeros((100, 4), np.float32)
    quats[1::3, 0] = 1e-40  # float32 denormal
    quats[2::3] = np.float32(1e-45)
    scene = scene_of(means, np.array([0.15, 0.05, 0.05]), quats)
    identity = scene_of(means, np.array([0.15, 0.05, 0.05]))
    gl = check(scene, packed=packed)
    np.testing.assert_array_equal(gl.rgba, QuadBackend(identity, packed=packed).render(CAM, Lens(4.0, 0.0)).rgba)


def test_opacity_logits_of_plus_minus_1e4_load_as_0_and_1(tmp_path):
    """exp(±1e4) overflows float32: the loader clamps the logit to ±87 (no overflow warning), giving
    opacity 1 exactly and sigmoid(−87) ≈ 1.6e-38 (0 to any drawing), and renders match."""
    means, q = cloud(100, seed=8)
    rows = scene_rows(scene_of(means, 0.1, q))
    rows["opacity"] = np.where(np.arange(100) % 2, 1e4, -1e4)
    path = tmp_path / "logits.ply"
    path.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 100\n"
                     + b"".join(f"property float {n}\n".encode() for n in rows.dtype.names)
                     + b"end_header\n" + rows.tobytes())
    with np.errstate(all="raise"):
        scene = read_ply(path)
    np.testing.assert_allclose(scene.opacities, np.where(np.arange(100) % 2, 1.0, 0.0), rtol=0, atol=1e-37)
    assert (scene.opacities[1::2] == 1.0).all()
    check(scene, Lens(3.0, 50.0))


@pytest.mark.parametrize("norm", ["none", "energy", "optical-depth"])
@pytest.mark.parametrize("packed", [False, True])
def test_opacity_exactly_0_or_1(norm, packed):
    means, q = cloud(200, seed=9)
    scene = scene_of(means, 0.1, q, opacities=np.where(np.arange(200) % 2, 1.0, 0.0))
    for lens in (Lens(4.0, 0.0), Lens(3.0, 80.0)):
        for dof in ("sliced", "splat"):  # the normalisation shapes the per-splat blur
            gl = check(scene, lens, RenderSettings(opacity_norm=norm, dof=dof), packed=packed)
            assert gl.alpha.max() <= 1.0


# ---- lens -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("focus", [1e-3, 0.03, 0.5, 5.0, 1e5, 1e30, math.inf])
def test_focus_in_front_of_at_and_far_beyond_all_content(focus):
    """Content spans z 4…6 and near = 0.01: focus below the near plane, in front, inside, beyond, ∞."""
    means, q = cloud(200, seed=10)
    scene = scene_of(means, 0.08, q)
    for settings in (RenderSettings(tau=0.0), RenderSettings(tau=2 / 255), RenderSettings(dof="splat")):
        check(scene, Lens(focus, 40.0), settings)


def test_physical_lens_focused_at_its_focal_length_is_refused():
    """Eq. 3 divides by d_f − f: focusing at (or inside) the focal length is a clear error."""
    lens = PhysicalLens(focal_mm=50.0, fnumber=2.0, units_per_metre=1.0)
    for focus in (0.05, 0.04, 0.05 * (1 - 1e-12)):
        with pytest.raises(DofviewError, match="must be beyond the focal length"):
            lens.strength(1000.0, focus)
    assert math.isfinite(lens.strength(1000.0, 0.05 * (1 + 1e-9)))


def test_focus_at_infinity_is_the_limit_of_far_focus():
    lens = PhysicalLens(focal_mm=50.0, fnumber=2.0, units_per_metre=1.0)
    assert lens.strength(1000.0, math.inf) == pytest.approx(lens.strength(1000.0, 1e12), rel=1e-9)
    means, q = cloud(200, seed=11)
    scene = scene_of(means, 0.08, q)
    r = QuadBackend(scene)
    at_inf = r.render(CAM, Lens(math.inf, 60.0))
    np.testing.assert_allclose(at_inf.rgba, r.render(CAM, Lens(1e12, 60.0)).rgba, atol=1e-6)
    check(scene, Lens(math.inf, 60.0))


@pytest.mark.parametrize("settings", [RenderSettings(), RenderSettings(tau=0.0), RenderSettings(dof="splat"),
                                      RenderSettings(opacity_norm="optical-depth", k=1.0, dof="splat"),
                                      RenderSettings(opacity_norm="none", blend_linear=True, dof="splat")])
def test_aperture_zero_is_bit_equal_to_the_pinhole_for_any_focus(settings):
    """Extends test_renderer's check to every setting and to focus distances whose inverse
    overflows float32 (1e-39: the uniform 1/d_f would be inf, and 0·inf a NaN blur)."""
    scene = random_scene(seed=12)
    r = QuadBackend(scene)
    pinhole = r.render(CAM, Lens(1.0, 0.0), settings)
    for focus in (1e-39, 1e-3, 1e30, math.inf):
        np.testing.assert_array_equal(r.render(CAM, Lens(focus, 0.0), settings).rgba, pinhole.rgba)


def _blend_bound(scene, settings):
    """Pixels that can pass α ≥ τ, for any aperture and k: a Gaussian blurred to Σ′ keeps
    α ≥ τ on an ellipse of area π·sqrt(det Σ′)·2·ln(o′/τ) with o′ = o·sqrt(det Σ₂/det Σ′); over all
    Σ′ that is at most 2π·o·sqrt(det Σ₂)/(τ·e). Grown by one pixel all round for pixel rounding."""
    pr = project(scene, CAM, Lens(1.0, 0.0), settings)
    sxx, sxy, syy = pr["cov"].T
    area = 2 * np.pi * scene.opacities[pr["idx"]] * np.sqrt(sxx * syy - sxy * sxy) / (settings.tau * np.e)
    return float(((np.sqrt(area) + np.sqrt(np.pi)) ** 2).sum())


def test_huge_apertures_stay_finite_and_bounded_in_cost():
    """CoC radii up to 15 000 px: images stay finite, and with τ > 0 the fragments blended (a GL
    samples-passed query) never exceed a bound that does not depend on the aperture; the number of
    Gaussians drawn falls as the blur pushes o·β below τ. With τ = 0 nothing is culled, so the image
    is checked against the reference instead (its cost is capped by the viewport)."""
    means, q = cloud(150, seed=13)
    rng = np.random.default_rng(13)
    scene = scene_of(means, np.exp(rng.uniform(math.log(0.02), math.log(0.5), (150, 1))), q,
                     opacities=rng.uniform(0.1, 1.0, 150))
    r = QuadBackend(scene)
    settings = RenderSettings(tau=2 / 255)
    bound = _blend_bound(scene, settings)
    drawn = []
    for coc in (0.0, 10.0, 100.0, 300.0, 1000.0, 15000.0):
        lens = Lens(2.0, coc / (0.5 * (1 / 2.0 - 1 / 5.0)))  # CoC radius `coc` px at z = 5
        query = r.ctx.query(samples=True)
        with query:
            r.draw(CAM, lens, settings, count=True)
        frame = r.read()
        assert np.isfinite(frame.rgba).all() and np.isfinite(frame.depth).all()
        assert 0 <= frame.alpha.min() and frame.alpha.max() <= 1.0
        assert query.samples <= bound
        drawn.append(r.stats.drawn)
    assert drawn[0] == scene.count and drawn == sorted(drawn, reverse=True)
    check(scene, Lens(2.0, 300.0 / 0.15), RenderSettings(tau=0.0))


# ---- HDR and exposure --------------------------------------------------------------------------------
def hdr_scene() -> GaussianScene:
    """Linear radiance log-uniform in 1…1e6 on a plane of overlapping Gaussians."""
    rng = np.random.default_rng(14)
    n = 200
    means = np.c_[rng.uniform(-1.5, 1.5, (n, 2)) * [1.0, 0.75], rng.uniform(4.8, 5.2, n)]
    radiance = np.exp(rng.uniform(0.0, math.log(1e6), (n, 1))) * [1.0, 0.5, 0.25]
    return GaussianScene(
        means=means, quats=np.tile([1.0, 0, 0, 0], (n, 1)), scales=np.full((n, 3), 0.2),
        opacities=np.full(n, 0.9), sh_dc=(radiance - 0.5) / SH_C0, colour_space="linear")


@pytest.mark.parametrize("packed", [False, True])
def test_hdr_radiance_up_to_1e6_matches_the_reference(packed):
    """Packed storage keeps colours as halves (max 65504): a power-of-two scale keeps 1e6."""
    gl = check(hdr_scene(), Lens(4.0, 30.0), packed=packed)
    assert gl.rgba[..., :3].max() > 1e5


@pytest.mark.parametrize("ev", [-20, 0, 20])
def test_half_exr_at_extreme_exposure_clips_at_half_max(tmp_path, ev):
    """`dofview render --half --exposure ±20`: no inf/NaN in any channel; colours beyond 65504 are
    clipped to exactly 65504, the rest equal the float32 EXR to half precision."""
    from dofview.cli import main

    scene_path = tmp_path / "hdr.ply"
    write_ply(hdr_scene(), scene_path)
    # --aperture holds at the --eye/--target reference width, 800 px: 375 is A = 30 at 64 px
    common = ["render", str(scene_path), "--eye", "0,0,0", "--target", "0,0,5", "--width", "64",
              "--height", "48", "--fov", "60", "--focus", "4", "--aperture", "375", "--exposure", str(ev),
              "--tonemap", "clip"]  # Eq. 7's clip (a linear scene's default display operator is adaptive)
    assert main([*common, "-o", str(tmp_path / "f.exr"), "--png", str(tmp_path / "f.png")]) == 0
    assert main([*common, "-o", str(tmp_path / "h.exr"), "--half"]) == 0
    full, _ = read_exr(tmp_path / "f.exr")
    half, _ = read_exr(tmp_path / "h.exr")
    for c in "RGBAZ":
        assert np.isfinite(full[c]).all() and np.isfinite(half[c]).all()
    rgb_f = np.stack([full[c] for c in "RGB"], -1).astype(np.float64)
    rgb_h = np.stack([half[c] for c in "RGB"], -1).astype(np.float64)
    assert half["R"].dtype == np.float16 and half["Z"].dtype == np.float32
    over = rgb_f > HALF_MAX
    assert (rgb_h[over] == HALF_MAX).all()
    np.testing.assert_allclose(rgb_h[~over], rgb_f[~over], rtol=2**-10, atol=2**-24)
    ref = render_reference(read_ply(scene_path), look_at([0, 0, 0], [0, 0, 5], 64, 48, 60), Lens(4.0, 30.0))
    expected = ref.rgba[..., :3] * 2.0**ev
    assert psnr(rgb_f, expected, expected.max()) >= 45.0
    assert over.any() == (ev >= 0)  # radiance 1e6 exceeds half range unless darkened
    # the PNG clips at display white where exposed radiance ≥ 1; at −20 EV even 1e6 stays below it
    png = read_png(tmp_path / "f.png").astype(int)
    exposed_max = rgb_f.max(-1)
    if ev >= 0:
        assert (png[exposed_max >= 1.0].max(-1) == 255).all()
    else:
        assert exposed_max.max() < 1.0 and png.max() < 255


# ---- depth order -------------------------------------------------------------------------------------
def test_depths_from_1e_minus_3_to_1e5_render_like_the_reference():
    """One Gaussian per depth over eight decades, each the same size on screen and slightly off
    axis, so every one is visible behind the nearer ones: the order must be exact across the range."""
    z = np.geomspace(1e-3, 1e5, 40)
    angle = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    means = np.c_[0.3 * z * np.cos(angle), 0.2 * z * np.sin(angle), z]
    scene = scene_of(means, (0.05 * z)[:, None], opacities=0.7)
    check(scene, Lens(1.0, 0.0), RenderSettings(near=1e-4))
    check(scene, Lens(1.0, 5.0), RenderSettings(near=1e-4))


def test_many_gaussians_at_equal_depth_are_stable_between_frames():
    """300 overlapping Gaussians on one depth plane: drawn in index order as the reference's stable
    sort does, and bit-identical after the camera moves away and back (no flicker)."""
    rng = np.random.default_rng(15)
    means = np.c_[rng.uniform(-0.5, 0.5, (300, 2)), np.full(300, 5.0)]
    scene = scene_of(means, 0.2, opacities=0.5, seed=15)
    first = check(scene, Lens(5.0, 0.0), RenderSettings(tau=0.0))
    r = QuadBackend(scene, packed=False)
    a = r.render(CAM, Lens(5.0, 0.0), RenderSettings(tau=0.0))
    r.render(look_at([0.3, 0.1, 0], [0, 0, 5], 64, 48, 60), Lens(5.0, 0.0))
    b = r.render(CAM, Lens(5.0, 0.0), RenderSettings(tau=0.0))
    np.testing.assert_array_equal(a.rgba, b.rgba)
    np.testing.assert_allclose(a.rgba, first.rgba, atol=1e-4)


# ---- empty, single, all culled ----------------------------------------------------------------------
def test_empty_scene_renders_an_empty_image():
    empty = scene_of(np.zeros((0, 3)), 0.1)
    assert_finite_and_empty(QuadBackend(empty).render(CAM, Lens(4.0, 50.0)))
    assert_finite_and_empty(render_reference(empty, CAM, Lens(4.0, 50.0)))


def test_one_gaussian():
    check(scene_of([[0.1, -0.1, 4.0]], 0.3), Lens(2.0, 30.0))


def test_all_gaussians_culled_give_an_empty_image():
    """All behind the camera, all off screen, or (the per-splat mode) all blurred below τ: nothing
    is drawn. (The sliced mode draws the last as a pinhole and spreads its light: test_renderer.)"""
    means, q = cloud(100, seed=16)
    for scene, lens, settings in ((scene_of(means * [1, 1, -1], 0.1, q), Lens(4.0, 0.0), RenderSettings()),
                                  (scene_of(means + [40.0, 0, 0], 0.1, q), Lens(4.0, 0.0), RenderSettings()),
                                  (scene_of(means, 0.05, q, opacities=0.5), Lens(0.5, 2000.0),
                                   RenderSettings(dof="splat"))):
        r = QuadBackend(scene)
        r.draw(CAM, lens, settings, count=True)
        assert r.stats.drawn == 0
        assert_finite_and_empty(r.read())
        assert_finite_and_empty(render_reference(scene, CAM, lens, settings))


# ---- output sizes -----------------------------------------------------------------------------------
@pytest.mark.parametrize("size", [(1, 1), (33, 17), (2, 3), (601, 3), (3, 401)])
def test_tiny_odd_and_very_wide_images(size):
    w, h = size
    scene = random_scene(seed=17)
    cam = look_at([0, 0, 0], [0, 0, 5], w, h, 60)
    gl = check(scene, Lens(4.5, 40.0), RenderSettings(tau=0.0), cam=cam, packed=True)
    assert gl.rgba.shape == (h, w, 4)


def test_size_above_the_gl_limit_is_a_clear_error():
    r = QuadBackend(random_scene(n=10))
    limit = min(r.ctx.info["GL_MAX_TEXTURE_SIZE"], *r.ctx.info["GL_MAX_VIEWPORT_DIMS"])
    for w, h in ((limit + 1, 4), (4, limit + 1)):
        with pytest.raises(DofviewError, match=f"{w}×{h} exceeds this OpenGL's limit of {limit}"):
            r.render(look_at([0, 0, 0], [0, 0, 5], w, h, 60), Lens(4.0, 0.0))
    assert r.render(look_at([0, 0, 0], [0, 0, 5], 8, 8, 60), Lens(4.0, 0.0)).rgba.shape == (8, 8, 4)
