"""The bundled samples: what the README promises of them, and the GL renderer against the CPU
reference on them (per-splat: A = 0 and two apertures, τ ∈ {0, 1/255, 2/255}; sliced: two apertures)."""

from pathlib import Path

import numpy as np
import pytest
from conftest import assert_matches_reference, assert_matches_sliced_reference, psnr

from dofview.bench import synth
from dofview.frame import RenderSettings
from dofview.io import load_scene
from dofview.io.cameras import load_cameras_json
from dofview.lens import Lens
from dofview.rendering.quad import QuadBackend
from dofview.rendering.reference import render_reference, render_reference_sliced

SAMPLES = Path(__file__).resolve().parent.parent / "samples"
FOCUS = {"cards": 4.0, "lamp": synth.LAMP_DEPTH}


@pytest.fixture(scope="module", params=["cards", "lamp"])
def sample(request):
    name = request.param
    scene = load_scene(SAMPLES / f"{name}.ply", progress=False)
    cams = load_cameras_json(SAMPLES / f"{name}_cameras.json")
    return name, scene, cams


def test_samples_are_small_and_equal_their_generator(sample):
    name, scene, cams = sample
    assert (SAMPLES / f"{name}.ply").stat().st_size < 2_000_000
    assert len(cams) >= 8
    fresh = {"cards": synth.cards_scene, "lamp": synth.lamp_scene}[name]()
    assert scene.count == fresh.count and scene.sh_degree == fresh.sh_degree
    assert scene.colour_space == fresh.colour_space
    np.testing.assert_array_equal(scene.means, fresh.means)
    np.testing.assert_allclose(scene.scales, fresh.scales, rtol=1e-6)
    np.testing.assert_allclose(scene.opacities, fresh.opacities, atol=1e-6)


def test_lamp_sample_is_hdr():
    scene = load_scene(SAMPLES / "lamp.ply", progress=False)
    lamp = synth.emissive_mask(scene)
    assert scene.colour_space == "linear"
    assert scene.base_colour()[lamp].min() >= 100 * scene.base_colour()[~lamp].max()


@pytest.mark.parametrize("aperture", [0.0, 30.0, 90.0])
@pytest.mark.parametrize("tau", [0.0, 1 / 255, 2 / 255])
def test_gl_matches_reference_on_samples(backend, sample, aperture, tau):
    """PSNR ≥ 45 dB on the linear image (peak: brightest value), and ≥ 45 dB on the image clipped
    to [0, 1] with peak 1 so the dim surfaces of the HDR sample are held to the same bound; depth
    within 1e-3 relative where α > 0.5."""
    name, scene, cams = sample
    cam = cams[1].resized(120, 90)
    lens, settings = Lens(FOCUS[name], aperture), RenderSettings(tau=tau, dof="splat")
    gl = backend(scene, packed=False).render(cam, lens, settings)
    ref = render_reference(scene, cam, lens, settings, margins=True)
    assert_matches_reference(gl, ref, max_near_cut=0.03)
    assert psnr(np.clip(gl.rgba, 0, 1), np.clip(ref[0].rgba, 0, 1)) >= 45.0


@pytest.mark.parametrize("aperture", [30.0, 90.0])
def test_sliced_gl_matches_reference_on_samples(backend, sample, aperture):
    """The default mode (sliced) against its CPU reference at the default τ, with the same two
    bars as the per-splat test above."""
    name, scene, cams = sample
    cam = cams[1].resized(120, 90)
    lens, settings = Lens(FOCUS[name], aperture), RenderSettings()
    gl = backend(scene, packed=False).render(cam, lens, settings)
    ref = render_reference_sliced(scene, cam, lens, settings)
    assert_matches_sliced_reference(gl, ref)
    assert psnr(np.clip(gl.rgba, 0, 1), np.clip(ref.rgba, 0, 1)) >= 45.0


def test_three_focus_distances_move_the_sharp_plane():
    """Focusing at each card's depth makes that card the sharpest of the three (gradient energy in
    its box), in the canonical view of the cards sample."""
    scene = load_scene(SAMPLES / "cards.ply", progress=False)
    cam = load_cameras_json(SAMPLES / "cards_cameras.json")[0].resized(400, 300)
    r = QuadBackend(scene)

    def sharpness(img, box):
        x0, y0, x1, y1 = (int(round(v)) for v in box)
        g = img[y0 + 4:y1 - 4, x0 + 4:x1 - 4, :3].mean(axis=2)
        return float(np.mean(np.diff(g, axis=0) ** 2) + np.mean(np.diff(g, axis=1) ** 2))

    for focused in synth.CARDS:
        frame = r.render(cam, Lens(synth.CARD_DEPTHS[focused.name], 120.0))
        s = {c.name: sharpness(frame.rgba, c.pixel_box(cam)) for c in synth.CARDS}
        pin = r.render(cam, Lens(1.0, 0.0))
        s_pin = {c.name: sharpness(pin.rgba, c.pixel_box(cam)) for c in synth.CARDS}
        rel = {k: s[k] / s_pin[k] for k in s}  # sharpness relative to the pinhole image of each card
        assert max(rel, key=rel.get) == focused.name
        assert rel[focused.name] > 0.8
