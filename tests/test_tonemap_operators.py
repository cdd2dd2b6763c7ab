"""Tone-mapping operators (dofview.tonemap.OPERATORS) against the invariances the project's
tone-mapping notes ask of them (docs/BENCHMARKS.md, "Tone mapping"), the temporal smoothing, the statistics, and the CLI's EXR/PNG contract.
The GLSL-vs-numpy comparison of every operator is test_renderer.py::test_gpu_tonemap_matches_numpy."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import psnr

from dofview.tonemap import LINEAR_DEFAULT, OPERATORS, StatsSmoother, Tonemap, display, to_uint8
from dofview.tonemap.operator import luminance
from dofview.tonemap.stats import (
    SMOOTHING_T0_S,
    clipped_crushed,
    frame_stats,
    pooled_stats,
)

ROOT = Path(__file__).resolve().parents[1]
ADAPTIVE = [n for n, c in OPERATORS.items() if c.adaptive]
H, W = 48, 64


def hdr_image(seed: int = 0) -> np.ndarray:
    """(H, W, 4) linear RGBA: smooth coloured radiance over 8 stops, a bright lamp disc 2^10 above
    the room, a black uncovered border."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:H, 0:W] / np.array([H, W])[:, None, None]
    base = np.exp2(-6 + 8 * x + rng.normal(0, 0.3, (H, W)))[..., None] * np.array([0.9, 1.0, 0.7]) * (1 + 0.3 * np.sin(9 * y))[..., None]
    lamp = (x - 0.7) ** 2 + (y - 0.3) ** 2 < 0.004
    base[lamp] = 2.0 ** 10
    rgba = np.concatenate([base, np.ones((H, W, 1))], -1)
    rgba[:4] = 0.0  # background: nothing drawn
    return rgba.astype(np.float32)


def depth_of(rgba: np.ndarray) -> np.ndarray:
    d = np.where(np.arange(W)[None, :] < W // 2, 3.0, 6.0) * np.ones((H, 1))
    return np.where(rgba[..., 3] > 0, d, 0.0).astype(np.float32)


def show(rgba: np.ndarray, name: str, exposure: float = 0.0, depth: np.ndarray | None = None) -> np.ndarray:
    tm = Tonemap(exposure=exposure, operator=OPERATORS[name]())
    return display(rgba, False, tm, depth=depth_of(rgba) if depth is None else depth)


@pytest.mark.parametrize("name", list(OPERATORS))
def test_output_in_unit_range_without_nan_on_degenerate_frames(name):
    frames = {"zero": np.zeros((H, W, 4), np.float32), "constant": np.concatenate([np.full((H, W, 3), 0.37), np.ones((H, W, 1))], -1),
              "hot": np.concatenate([np.zeros((H, W, 3)), np.ones((H, W, 1))], -1), "scene": hdr_image()}
    frames["hot"][5, 7, :3] = 1e6
    frames["uncovered"] = frames["constant"] * np.array([1, 1, 1, 0])
    for what, rgba in frames.items():
        out = show(rgba.astype(np.float32), name)
        assert np.isfinite(out).all() and out.min() >= 0.0 and out.max() <= 1.0, what


@pytest.mark.parametrize("name", list(OPERATORS))
def test_grey_in_grey_out_and_monotone_luminance(name):
    """A grey log ramp (16 stops along x, one row per value, at one depth: across a depth edge the
    bilateral operator's base steps on purpose): channels stay equal and the output luminance
    never decreases with the input — scene-referred at 0 EV, and display-referred (an encoded
    ramp up to white) at +3 EV, where its top is compressed."""
    ramp = np.exp2(np.linspace(-10, 6, W))
    rgba = np.ones((H, W, 4), np.float32)
    rgba[..., :3] = ramp[None, :, None]
    encoded = rgba.copy()
    encoded[..., :3] = np.exp2(np.linspace(-10, 0, W))[None, :, None]
    depth = np.full((H, W), 4.0, np.float32)
    for out in (show(rgba, name, depth=depth),
                display(encoded, True, Tonemap(exposure=3.0, operator=OPERATORS[name]()), depth=depth)):
        grey = 1e-5  # OpenColorIO (aces) computes in float32; 1/255 is 4e-3
        np.testing.assert_allclose(out[..., 0], out[..., 1], atol=grey)
        np.testing.assert_allclose(out[..., 1], out[..., 2], atol=grey)
        lum = luminance(out)[H // 2]
        assert (np.diff(lum) >= -1e-9).all(), np.diff(lum).min()
        assert lum[-1] > lum[0]


@pytest.mark.parametrize("name", ADAPTIVE)
def test_statistics_follow_a_scaled_scene_and_the_picture_does_not_change(name):
    """The scene ×16: statistics shift by exactly 4 stops; the picture stays (≥ 35 dB, TONEMAP.md)."""
    rgba = hdr_image()
    scaled = rgba.copy()
    scaled[..., :3] *= 16.0
    op = OPERATORS[name]()
    s1, s16 = frame_stats(rgba, op), frame_stats(scaled, op)
    np.testing.assert_allclose(s16.scalars()[:6], s1.scalars()[:6] + 4.0, atol=1e-3)  # float32 log2 at bin edges
    assert psnr(show(rgba, name), show(scaled, name)) >= 35.0


HOT_PIXEL_MIN_PSNR = 40.0


@pytest.mark.parametrize("name", ADAPTIVE)
def test_one_pixel_at_ten_thousand_times_the_maximum_barely_changes_the_picture(name):
    """Robust statistics: one pixel at 10⁴× the frame's maximum leaves every other pixel within
    HOT_PIXEL_MIN_PSNR dB (a raw min/max normalisation would darken the whole frame)."""
    rgba = hdr_image()
    hot = rgba.copy()
    hot[30, 10, :3] = 1e4 * rgba[..., :3].max()
    a, b = show(rgba, name), show(hot, name)
    keep = np.ones((H, W), bool)
    keep[30, 10] = False
    assert psnr(a[keep], b[keep]) >= HOT_PIXEL_MIN_PSNR


def test_background_is_excluded_from_the_statistics():
    rgba = hdr_image()
    more_background = np.concatenate([rgba, np.zeros((H, W, 4), np.float32)], 1)
    op = OPERATORS["histogram"]()
    np.testing.assert_allclose(frame_stats(more_background, op).scalars(), frame_stats(rgba, op).scalars())


def test_joint_statistics_pool_the_histograms():
    """--stats joint: two views pooled give the statistics of both side by side."""
    a, b = hdr_image(1), hdr_image(2)
    b[..., :3] *= 3.0
    op = OPERATORS["histogram"]()
    joint, side = pooled_stats([a, b], op), frame_stats(np.concatenate([a, b], 1), op)
    np.testing.assert_allclose(joint.scalars(), side.scalars())
    np.testing.assert_allclose(joint.cdf, side.cdf)


def _step_response(fps: float, seconds: float) -> float:
    from dofview.tonemap.stats import Stats

    sm = StatsSmoother()
    sm.update(Stats(count=1), 0.0)
    step = Stats(lo=1.0, hi=1.0, key=1.0, channel_key=(1.0, 1.0, 1.0), count=1)
    frames = round(seconds * fps)
    for _ in range(frames):
        s = sm.update(step, 1.0 / fps)
    return s.key


def test_smoothing_step_response_and_frame_rate_independence():
    """S_t = w·S_(t−1) + (1−w)·S with w = exp(−Δt/t0): 63.2% of a step at t0 (1 − 1/e), and the
    same curve at 30 and 144 frames per second after 1 s."""
    fps = 1.0 / (SMOOTHING_T0_S / 30)  # 30 frames per t0
    assert _step_response(fps, SMOOTHING_T0_S) == pytest.approx(1 - math.exp(-1), abs=1e-9)
    assert _step_response(30, 1.0) == pytest.approx(_step_response(144, 1.0), abs=1e-9)
    assert _step_response(30, 1.0) == pytest.approx(1 - math.exp(-1.0 / SMOOTHING_T0_S), abs=1e-9)


def test_lock_freezes_the_statistics():
    from dofview.tonemap.stats import Stats

    sm = StatsSmoother()
    first = sm.update(Stats(key=-3.0, count=1), 0.0)
    sm.locked = True
    assert sm.update(Stats(key=5.0, count=1), 1.0).key == first.key


def test_clip_is_eq7_unchanged():
    """clip, the default, is exactly the display transform dofview had before operators:
    min(exposure·C, 1)^(1/γ), bit for bit."""
    rgba = hdr_image()
    for tm in (Tonemap(), Tonemap(exposure=math.log2(0.01), gamma=1.8)):
        old = np.power(np.clip(np.nan_to_num(rgba[..., :3].astype(np.float64) * tm.multiplier, nan=0.0, posinf=1.0), 0.0, 1.0), 1.0 / tm.gamma)
        assert np.array_equal(to_uint8(display(rgba, False, tm)), to_uint8(old))
        assert np.array_equal(display(rgba, False, tm), old)


def _lamp_view(name: str) -> tuple[float, float]:
    from dofview.io import load_scene
    from dofview.io.cameras import load_cameras_json
    from dofview.lens import Lens
    from dofview.rendering.quad import QuadBackend

    r = QuadBackend(load_scene(ROOT / "samples" / "lamp.ply"))
    frame = r.render(load_cameras_json(ROOT / "samples" / "lamp_cameras.json")[0].resized(160, 120), Lens(2.5, 0.0))
    return clipped_crushed(r.display_image(Tonemap(operator=OPERATORS[name]())), frame.alpha)


@pytest.mark.parametrize("name", ADAPTIVE)
def test_adaptive_operators_neither_clip_nor_crush_the_lamp(name):
    """samples/lamp.ply, view 0 at 0 EV: ≤ 2% of covered pixels clipped, ≤ 10% crushed."""
    clipped, crushed = _lamp_view(name)
    assert clipped <= 0.02 and crushed <= 0.10, (clipped, crushed)


def test_exr_is_unchanged_by_the_operator_and_records_it(tmp_path):
    from dofview.io.exr import read_exr

    common = [sys.executable, "-m", "dofview", "render", str(ROOT / "samples" / "lamp.ply"), "--width", "64", "--height", "48",
              "--focus", "3"]
    out = {}
    for name in ("clip", "histogram"):
        res = subprocess.run([*common, "-o", str(tmp_path / f"{name}.exr"), "--png", str(tmp_path / f"{name}.png"),
                              "--tonemap", name], capture_output=True, text=True, check=False)
        assert res.returncode == 0, res.stderr
        out[name] = read_exr(tmp_path / f"{name}.exr")
    (a, _), (b, header) = out["clip"], out["histogram"]
    assert set(a) == set(b) and all(np.array_equal(a[k], b[k]) for k in a)
    assert '"operator": "histogram"' in header["dofview:tonemap"] and "key_log2" in header["dofview:tonemap_stats"]
    assert (tmp_path / "clip.png").read_bytes() != (tmp_path / "histogram.png").read_bytes()


def test_operator_flags_are_checked():
    res = subprocess.run([sys.executable, "-m", "dofview", "render", str(ROOT / "samples" / "lamp.ply"), "-o", "x.exr",
                          "--histogram-saturation", "0.5"], capture_output=True, text=True, cwd=ROOT, check=False)
    assert res.returncode == 2 and res.stderr.strip() == "dofview: error: --histogram-saturation needs --tonemap histogram"
    res = subprocess.run([sys.executable, "-m", "dofview", "render", str(ROOT / "samples" / "lamp.ply"), "-o", "x.exr",
                          "--tonemap", "reinhard05", "--reinhard05-b", "9"], capture_output=True, text=True, cwd=ROOT, check=False)
    assert res.returncode == 2 and "brightness b must be in [-8, 8]" in res.stderr and "Traceback" not in res.stderr


def test_sequence_frames_are_smoothed_with_the_frame_interval(tmp_path):
    """save_render with one StatsSmoother over a sequence (the --frames hook): the second frame's
    recorded statistics are w·first + (1 − w)·its own, w = exp(−Δt/t0) with Δt = 1/fps."""
    import json

    from dofview.api import save_render
    from dofview.camera import look_at
    from dofview.frame import RenderSettings
    from dofview.io import load_scene
    from dofview.io.exr import read_exr
    from dofview.lens import Lens
    from dofview.rendering.quad import QuadBackend

    r = QuadBackend(load_scene(ROOT / "samples" / "lamp.ply"))
    cams = [look_at([0, 0, 0], target, 64, 48, 50) for target in ([-2, 0.3, 4.5], [1.0, -0.55, 4.5])]  # room, lamp
    tm, fps = Tonemap(operator=OPERATORS["reinhard05"]()), 24.0
    smoother, keys = StatsSmoother(), []
    for i, cam in enumerate(cams):
        frame = save_render(r, cam, Lens(3.0, 0.0), tm, RenderSettings(), "lamp.ply", tmp_path / f"f{i}.exr",
                            smoother=smoother, dt=1.0 / fps)
        keys.append((json.loads(read_exr(tmp_path / f"f{i}.exr")[1]["dofview:tonemap_stats"])["key_log2"],
                     frame_stats(frame.rgba, tm.operator).key))
    w = math.exp(-1.0 / fps / SMOOTHING_T0_S)
    assert keys[0][0] == pytest.approx(keys[0][1])
    assert abs(keys[1][1] - keys[0][1]) > 0.01  # the two views differ
    assert keys[1][0] == pytest.approx(w * keys[0][1] + (1 - w) * keys[1][1], abs=1e-9)


def test_render_stats_joint(tmp_path):
    """dofview render --stats joint records (and tone maps with) the statistics pooled over every
    view of --cameras; without --cameras it is refused before anything is written."""
    import json

    from dofview.api import joint_stats
    from dofview.io import load_scene
    from dofview.io.cameras import load_cameras_json
    from dofview.io.exr import read_exr
    from dofview.rendering.quad import QuadBackend

    lamp, cameras = ROOT / "samples" / "lamp.ply", ROOT / "samples" / "lamp_cameras.json"
    base = [sys.executable, "-m", "dofview", "render", str(lamp), "-o", str(tmp_path / "j.exr"), "--width", "64",
            "--height", "48", "--focus", "3", "--tonemap", "histogram", "--stats", "joint"]
    res = subprocess.run(base, capture_output=True, text=True, check=False)
    assert res.returncode == 2 and "--stats joint pools the views of --cameras" in res.stderr
    assert not (tmp_path / "j.exr").exists()
    res = subprocess.run([*base, "--cameras", str(cameras)], capture_output=True, text=True, check=False)
    assert res.returncode == 0, res.stderr
    got = json.loads(read_exr(tmp_path / "j.exr")[1]["dofview:tonemap_stats"])
    expected = joint_stats(QuadBackend(load_scene(lamp)), load_cameras_json(cameras), OPERATORS["histogram"]())
    assert got["key_log2"] == pytest.approx(expected.key, abs=1e-9) and got["lo_log2"] == pytest.approx(expected.lo, abs=1e-9)


# ---- compress only what the display cannot show (issue 20) ------------------------------------
SRGB_SCENES = [ROOT / "tests" / "data" / n for n in ("biker.spz", "burger.ply", "guitar.compressed.ply", "tap.spz",
                                                      "two_planes.ply")] + [ROOT / "samples" / "cards.ply"]
TRAINED_MIN_PSNR = 30.0
TRAINED_MEAN_RATIO = 0.10


def _mean_display_luminance(img: np.ndarray, alpha: np.ndarray) -> float:
    return float(luminance((img.astype(np.float64) / 255.0) ** 2.2)[alpha > 0.5].mean())


@pytest.mark.parametrize("path", SRGB_SCENES, ids=lambda p: p.name)
def test_display_referred_scenes_keep_their_trained_look(path):
    """Each sRGB-trained scene (tests/data, samples/cards.ply), one view at 160×120, on the GPU as
    the viewer shows it: at 0 EV every adaptive operator is within 30 dB of the trained look
    (clip) and its mean display luminance within ±10% (its values are display values and fit
    under white); at +2 EV no more pixels clip than with clip, and fewer where the frame's 99th
    percentile then lies above white (the range beyond the display is compressed)."""
    from inria_folder import ring_cameras

    from dofview.io import load_scene
    from dofview.lens import Lens
    from dofview.rendering.quad import QuadBackend

    scene = load_scene(path, progress=False)
    assert scene.colour_space == "srgb"
    r = QuadBackend(scene)
    frame = r.render(ring_cameras(path, 1)[0], Lens(1.0, 0.0))
    for ev in (0.0, 2.0):
        trained = r.display_image(Tonemap(exposure=ev))
        for name in ADAPTIVE:
            img = r.display_image(Tonemap(exposure=ev, operator=OPERATORS[name]()))
            if ev == 0.0:
                assert psnr(img / 255.0, trained / 255.0) >= TRAINED_MIN_PSNR, name
                ratio = _mean_display_luminance(img, frame.alpha) / _mean_display_luminance(trained, frame.alpha)
                assert abs(ratio - 1.0) <= TRAINED_MEAN_RATIO, (name, ratio)
            else:
                beyond = frame_stats(frame.rgba ** np.array([2.2, 2.2, 2.2, 1.0], np.float32), OPERATORS[name]()).hi + ev > 0
                ours, clip = clipped_crushed(img, frame.alpha)[0], clipped_crushed(trained, frame.alpha)[0]
                assert ours < clip if beyond else ours <= clip, (name, ours, clip)
    r.release()


def test_hdr_version_of_a_real_capture_neither_clips_nor_crushes():
    """tests/data/biker.spz made linear HDR (bench.tonemap_consistency.hdr_variant: four places at
    50–500× its diffuse white): at 0 EV each adaptive operator clips ≤ 2% and crushes ≤ 10% of
    the covered pixels, where clip at 0 EV shows the lights beyond the display."""
    from inria_folder import ring_cameras

    from dofview.bench.tonemap_consistency import hdr_variant
    from dofview.io import load_scene
    from dofview.lens import Lens
    from dofview.rendering.quad import QuadBackend

    path = ROOT / "tests" / "data" / "biker.spz"
    r = QuadBackend(hdr_variant(load_scene(path, progress=False)))
    frame = r.render(ring_cameras(path, 1)[0], Lens(1.0, 0.0))
    covered_rgb = frame.rgba[frame.alpha > 0.5, :3]
    assert covered_rgb.max() >= 50.0 and np.median(covered_rgb) < 1.0  # lights in view, a diffuse scene around them
    for name in ADAPTIVE:
        clipped, crushed = clipped_crushed(r.display_image(Tonemap(operator=OPERATORS[name]())), frame.alpha)
        assert clipped <= 0.02 and crushed <= 0.10, (name, clipped, crushed)
    r.release()


def _keyed_image(low_key: bool) -> np.ndarray:
    """(H, W, 4) linear grey over the same 12 stops [2^−8, 2^4]: 90% of the pixels in its darkest
    two stops (low key) or its brightest two (high key), the rest spread over the range."""
    rng = np.random.default_rng(3)
    n = H * W
    bulk = rng.uniform(-8.0, -6.0, n) if low_key else rng.uniform(2.0, 4.0, n)
    stops = np.where(rng.random(n) < 0.9, bulk, rng.uniform(-8.0, 4.0, n))
    rgba = np.ones((H, W, 4), np.float32)
    rgba[..., :3] = np.exp2(stops).reshape(H, W, 1)
    return rgba


@pytest.mark.parametrize("name", ADAPTIVE)
def test_scene_referred_key_follows_the_distribution(name):
    """Scene-referred: a low-key HDR frame comes out darker on average than a high-key one with the
    same range (the automatic key, not a fixed 0.18), and ×16 still changes nothing."""
    low, high = (show(_keyed_image(k), name, depth=np.full((H, W), 4.0, np.float32)) for k in (True, False))
    assert luminance(low).mean() < 0.5 * luminance(high).mean()
    scaled = _keyed_image(True)
    scaled[..., :3] *= 16.0
    assert psnr(show(scaled, name, depth=np.full((H, W), 4.0, np.float32)), low) >= 35.0


@pytest.mark.parametrize("name", ADAPTIVE)
def test_display_referred_values_are_display_values(name):
    """Display-referred (an encoded sRGB blend): a frame under white is shown exactly as clip
    shows it, and the same frame ×1/8 — a dark scene — is shown 8× darker, not re-exposed."""
    rng = np.random.default_rng(4)
    rgba = np.ones((H, W, 4), np.float32)
    rgba[..., :3] = rng.uniform(0.02, 0.95, (H, W, 3))
    depth = np.full((H, W), 4.0, np.float32)
    tm = Tonemap(operator=OPERATORS[name]())
    for scale in (1.0, 0.125):
        dark = rgba.copy()
        dark[..., :3] = (dark[..., :3] ** 2.2 * scale) ** (1 / 2.2)  # display-encoded, scale in linear light
        np.testing.assert_allclose(display(dark, True, tm, depth=depth), display(dark, True, Tonemap(), depth=depth),
                                   atol=1e-6)


@pytest.mark.parametrize("name", ADAPTIVE)
def test_exposure_through_white_changes_the_picture_continuously(name):
    """Raising the exposure of a display-referred frame across the point where its top reaches
    white moves no pixel by more than a small step per 1/20 EV (no switch between 'fits' and
    'compress' — seams and flicker; seed 004 §6.2.2)."""
    rng = np.random.default_rng(5)
    rgba = np.ones((H, W, 4), np.float32)
    rgba[..., :3] = rng.uniform(0.02, 0.95, (H, W, 3))
    depth = np.full((H, W), 4.0, np.float32)
    stats = frame_stats(rgba ** np.array([2.2, 2.2, 2.2, 1.0], np.float32), OPERATORS[name](), display_referred=True)
    shown = [display(rgba, True, Tonemap(exposure=ev, operator=OPERATORS[name]()), stats, depth)
             for ev in np.arange(-0.5, 0.5001, 0.05)]
    steps = [np.abs(b - a).max() for a, b in zip(shown, shown[1:])]
    assert max(steps) <= 0.03, max(steps)  # 1/20 EV moves a mid-grey pixel by ~0.009 at γ 2.2


def test_default_operator_follows_the_colour_space(tmp_path):
    """--tonemap auto (the default): clip for an sRGB scene, LINEAR_DEFAULT for a linear HDR one;
    the EXR stays linear either way."""
    import json

    from dofview.io.exr import read_exr

    for scene, expected in (("cards.ply", "clip"), ("lamp.ply", LINEAR_DEFAULT)):
        out = tmp_path / f"{scene}.exr"
        res = subprocess.run([sys.executable, "-m", "dofview", "render", str(ROOT / "samples" / scene), "-o", str(out),
                              "--png", str(tmp_path / f"{scene}.png"), "--width", "64", "--height", "48", "--focus", "3"],
                             capture_output=True, text=True, check=False)
        assert res.returncode == 0, res.stderr
        assert json.loads(read_exr(out)[1]["dofview:tonemap"])["operator"] == expected


def test_smoothed_statistics_change_the_curve_less_along_an_orbit():
    """bench.tonemap_consistency on a short orbit of samples/lamp.ply (6 frames, 80×60, 40°, the
    lamp coming into view): the display change the tone curve alone makes between frames, over
    depth-reprojected corresponding pixels, is smaller with the default smoothing than per frame,
    and a frame shown with its own statistics makes none."""
    from dofview.bench.tonemap_consistency import correspondence, measure, orbit
    from dofview.io import load_scene
    from dofview.io.cameras import load_cameras_json
    from dofview.lens import Lens
    from dofview.rendering.quad import QuadBackend

    r = QuadBackend(load_scene(ROOT / "samples" / "lamp.ply", progress=False))
    start = load_cameras_json(ROOT / "samples" / "lamp_cameras.json")[0]
    cams = orbit(start.centre + 3.0 * start.forward, start.centre, 6, 40.0, 80, 60)
    a, b = (r.render(c, Lens(1.0, 0.0)) for c in cams[:2])
    assert len(correspondence(cams[0], a.depth, cams[1], b.depth)[0]) > 0.5 * a.depth.size  # most of the room seen twice
    assert len(correspondence(cams[0], a.depth, cams[0], a.depth)[0]) == a.depth.size  # a frame matches itself
    op = OPERATORS[LINEAR_DEFAULT]()
    per_frame, smoothed = (measure(r, cams, op, t0, 24.0) for t0 in (None, SMOOTHING_T0_S))
    assert np.mean(smoothed["curve"]) < np.mean(per_frame["curve"])
    r.release()
