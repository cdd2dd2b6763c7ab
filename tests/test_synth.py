import time

import numpy as np
import pytest

from dofview.bench import synth
from dofview.scene import GaussianScene

ARRAYS = ("means", "quats", "scales", "opacities", "sh_dc", "sh_rest")


def _arrays(scene: GaussianScene) -> dict[str, np.ndarray]:
    return {k: getattr(scene, k) for k in ARRAYS if getattr(scene, k) is not None}


def _assert_valid(scene: GaussianScene) -> None:
    for name, a in _arrays(scene).items():
        assert a.dtype == np.float32, name
        assert np.all(np.isfinite(a)), name
    assert np.all(scene.scales > 0)
    assert np.all((scene.opacities >= 0) & (scene.opacities <= 1))
    assert np.allclose(np.linalg.norm(scene.quats, axis=1), 1.0, atol=1e-5)


@pytest.mark.parametrize("make", [synth.cards_scene, synth.lamp_scene,
                                  lambda seed: synth.random_scene(5000, degree=2, seed=seed)])
def test_deterministic_per_seed(make):
    a, b, c = make(seed=3), make(seed=3), make(seed=4)
    for k, v in _arrays(a).items():
        assert np.array_equal(v, getattr(b, k)), k
    assert any(not np.array_equal(v, getattr(c, k)) for k, v in _arrays(a).items())


def test_cards_scene_contents():
    s = synth.cards_scene()
    _assert_valid(s)
    assert s.colour_space == "srgb" and s.sh_rest is None and s.sh_degree == 0
    assert 15_000 <= s.count <= 25_000
    assert s.count * 80 < 2_000_000  # binary PLY: 20 float32 per Gaussian
    assert np.all((s.opacities >= 0.9) & (s.opacities <= 0.99))
    base = s.base_colour()
    assert base.min() >= 0 and base.max() <= 1


def test_cards_at_documented_depths():
    cams = synth.cards_cameras(800, 600)
    canon = cams[0]
    assert canon.name == "view_000"
    assert np.allclose(canon.R, np.eye(3)) and np.allclose(canon.T, 0)
    assert synth.CARD_DEPTHS == {"near": 2.0, "mid": 4.0, "far": 8.0}
    scene = synth.cards_scene()
    cam_pts = canon.world_to_camera(scene.means)
    for card in synth.CARDS:
        centre = canon.world_to_camera(np.array([card.centre]))[0]
        assert centre[2] == pytest.approx(synth.CARD_DEPTHS[card.name])
        # The card is fully inside the canonical image.
        x0, y0, x1, y1 = card.pixel_box(canon)
        assert 0 <= x0 < x1 <= 800 and 0 <= y0 < y1 <= 600
        # Its Gaussians really are there, at that depth.
        h = card.size / 2
        on = (np.abs(cam_pts[:, 0] - centre[0]) < h) & (np.abs(cam_pts[:, 1] - centre[1]) < h) \
            & (np.abs(cam_pts[:, 2] - centre[2]) < 0.01)
        assert on.sum() == card.texels ** 2
    # Separated depths, all in front of the wall.
    depths = sorted(synth.CARD_DEPTHS.values())
    assert all(b >= 1.9 * a for a, b in zip(depths, depths[1:]))
    assert depths[-1] < synth.WALL_DEPTH
    assert np.all(cam_pts[:, 2] <= synth.WALL_DEPTH * 1.001)


def test_card_centres_do_not_overlap_in_canonical_view():
    canon = synth.cards_cameras()[0]
    boxes = [c.pixel_box(canon) for c in synth.CARDS]
    for c, box in zip(synth.CARDS, boxes):
        cx, cy = canon.project(np.array([c.centre]))[0]
        for other, (x0, y0, x1, y1) in zip(synth.CARDS, boxes):
            if other is not c:
                assert not (x0 <= cx <= x1 and y0 <= cy <= y1)


@pytest.mark.parametrize("make_cams", [synth.cards_cameras, synth.lamp_cameras])
def test_cameras(make_cams):
    cams = make_cams(640, 480)
    assert 8 <= len(cams) <= 12
    assert [c.name for c in cams] == [f"view_{i:03d}" for i in range(len(cams))]
    assert all(c.width == 640 and c.height == 480 for c in cams)
    assert np.allclose(cams[0].centre, 0) and np.allclose(cams[0].forward, [0, 0, 1])
    fwd = np.array([c.forward for c in cams])
    angles = np.degrees(np.arccos(np.clip(fwd @ [0, 0, 1.0], -1, 1)))
    assert angles.max() <= 25 and len({tuple(np.round(c.centre, 6)) for c in cams}) == len(cams)
    # Image "up" is world −y for every view.
    assert all(c.R[1, 1] > 0.9 for c in cams)


def test_lamp_scene_contents_and_brightness():
    s = synth.lamp_scene()
    _assert_valid(s)
    assert s.colour_space == "linear" and s.sh_degree == 3
    assert s.count <= 7000
    assert s.count * 62 * 4 < 2_000_000  # binary PLY: 62 float32 per degree-3 Gaussian
    base = s.base_colour()
    lamp = synth.emissive_mask(s)
    assert 50 <= lamp.sum() <= 500
    diffuse = base[~lamp]
    assert diffuse.max() <= synth.MAX_DIFFUSE_RADIANCE + 1e-6
    assert diffuse.max() >= 0.3  # some surfaces are properly lit
    assert np.all(base[lamp] >= np.array(synth.LAMP_RADIANCE) * (1 - 1e-5))
    assert base[lamp].min() >= 100 * diffuse.max()
    # Even with the view-dependent terms (|SH basis| < 1) diffuse surfaces stay far below the lamp.
    bound = diffuse + np.abs(s.sh_rest[~lamp]).sum(axis=1)
    assert bound.max() <= 0.6 and base[lamp].min() >= 100 * bound.max()
    # The lamp is where it is documented to be.
    centre = s.means[lamp].mean(axis=0)
    assert np.allclose(centre, synth.LAMP_POSITION, atol=0.02)
    assert np.linalg.norm(s.means[lamp] - synth.LAMP_POSITION, axis=1).max() <= synth.LAMP_RADIUS
    canon = synth.lamp_cameras()[0]
    assert canon.world_to_camera(np.array([synth.LAMP_POSITION]))[0, 2] == pytest.approx(synth.LAMP_DEPTH)


def test_lamp_scene_has_some_view_dependence():
    s = synth.lamp_scene()
    glossy = np.abs(s.sh_rest).sum(axis=(1, 2)) > 0
    assert 100 <= glossy.sum() < s.count // 2
    assert np.abs(s.sh_rest[glossy, 8:]).max() > 0  # degree-3 bands are exercised


def test_random_scene_million_is_fast_and_lean():
    t0 = time.perf_counter()
    s = synth.random_scene(1_000_000)
    elapsed = time.perf_counter() - t0
    assert s.count == 1_000_000 and s.sh_rest is None
    for name, a in _arrays(s).items():
        assert a.dtype == np.float32, name
    assert s.means.shape == (1_000_000, 3) and s.quats.shape == (1_000_000, 4)
    assert s.scales.shape == (1_000_000, 3) and s.opacities.shape == (1_000_000,)
    assert all(np.all(np.isfinite(a)) for a in _arrays(s).values())
    assert elapsed < 4.0  # ~0.3 s on a laptop; generous for loaded CI machines


def test_random_scene_layout():
    s = synth.random_scene(20_000, degree=3, seed=1)
    _assert_valid(s)
    assert s.sh_rest.shape == (20_000, 15, 3)
    z = s.means[:, 2]
    assert z.min() >= 2.0 - 1e-4 and z.max() <= 20.0 + 1e-4
    cam = synth.benchmark_camera()
    px = cam.project(s.means)
    inside = (px[:, 0] >= 0) & (px[:, 0] < 1280) & (px[:, 1] >= 0) & (px[:, 1] < 720)
    assert inside.mean() > 0.75
    # Median footprint: a few pixels at this count (see the docstring).
    sigma_px = np.median(s.scales.mean(axis=1) * cam.fx / z)
    assert 1.0 < sigma_px < 10.0
    assert synth.random_scene(0).count == 0


def test_single_gaussian():
    s = synth.single_gaussian((0.1, -0.2, 5.0), 0.05, opacity=0.3, colour=(0.2, 0.4, 0.6))
    _assert_valid(s)
    assert s.count == 1
    assert np.allclose(s.means[0], [0.1, -0.2, 5.0]) and np.allclose(s.scales[0], 0.05)
    assert s.opacities[0] == pytest.approx(0.3)
    assert np.allclose(s.base_colour()[0], [0.2, 0.4, 0.6], atol=1e-6)
    assert synth.single_gaussian((0, 0, 1), 1.0, colour_space="linear").colour_space == "linear"
