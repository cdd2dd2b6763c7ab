"""Deep output of the sliced depth of field (issue 29; rendering/deep_sliced.py): the blurred layers
as samples over their depth ranges, read from the GPU's composite on both backends. Flattened,
they give the flat frame of the same render; a CG element merged between two planes' layers lands
between them; the command line writes them with the default settings and an aperture."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import psnr, random_scene
from inria_folder import SCENES, ring_cameras

from dofview.bench.deep import card, joined
from dofview.camera import look_at
from dofview.cli import main
from dofview.deep import DeepFrame, DeepSettings
from dofview.io import load_scene
from dofview.io.exr import read_deep_exr, read_exr
from dofview.lens import Lens
from dofview.rendering.reference import render_reference_sliced, render_reference_sliced_deep

pytestmark = pytest.mark.filterwarnings("ignore:.*trained with antialiasing")
CAM = look_at([0.0, 0.0, 0.0], [0.0, 0.0, 5.0], 64, 48, 60)
LENS = Lens(8.0, 40.0)  # focused on the back plane; the front one blurred by 7.5 px
CG = (0.1, 0.8, 0.2)


def _db(a: np.ndarray, b: np.ndarray) -> float:
    return psnr(a, b, max(1.0, float(b.max())))


def _planes() -> tuple:
    """A small red card at z = 2 in front of a blue wall at z = 8 filling the view (linear colour:
    a compositor's merge and the renderer's blend are in the same space)."""
    like = random_scene(10, colour_space="linear")
    front = card(CAM, 2.0, like, box=(0.3, 0.6, 0.3, 0.7), colour=(0.9, 0.1, 0.1), opacity=0.9)
    back = card(CAM, 8.0, like, box=(-0.1, 1.1, -0.1, 1.1), colour=(0.1, 0.2, 0.9), opacity=0.9)
    return front, back


def _check_tidy(image: DeepFrame) -> None:
    """Samples front to back without overlapping, Z ≤ ZBack, alphas in [0, 1]."""
    z, back = image.depth[:, 0], image.depth[:, 1]
    pix = np.repeat(np.arange(image.counts.size), image.counts.ravel())
    nxt = pix[1:] == pix[:-1]
    assert np.all(back >= z) and np.all(z[1:][nxt] >= back[:-1][nxt])
    assert np.all((image.rgba[:, 3] >= 0) & (image.rgba[:, 3] <= 1))


@pytest.mark.parametrize("name", ["burger.ply", "two_planes.ply", "guitar.compressed.ply"])
def test_sliced_deep_flattens_to_the_frame_of_the_same_render(backend, name):
    scene = load_scene(SCENES / name, progress=False)
    camera = ring_cameras(SCENES / name, size=(120, 90))[1]
    lens = Lens(1.6, 40.0)
    renderer = backend(scene)
    try:
        flat = renderer.render(camera, lens).rgba
        image = renderer.deep(camera, lens)
        again = renderer.read().rgba  # the deep image's own draw, left in the targets
        layers = len(renderer.sliced_layers)
    finally:
        renderer.release()
    assert np.array_equal(again, flat)
    assert image.samples > image.counts.size // 4 and image.counts.max() > 1 and layers != 1
    assert _db(image.flatten(), flat) >= 50.0
    _check_tidy(image)
    assert image.sorted() is image


def test_a_cg_plane_merged_between_two_planes_lands_between_them(backend):
    """A semi-transparent CG plane at z = 4, merged into the deep image of a card at z = 2 (blurred)
    in front of a wall at z = 8, flattened: the card rendered alone, over the plane, over the wall
    rendered alone (≥ 40 dB; both renders made independently of the deep image's layers). Merged in
    front of everything instead, it is ≥ 10 dB further off."""
    front, back = _planes()
    out = {}
    for key, scene in (("both", joined(front, back)), ("front", front), ("back", back)):
        renderer = backend(scene)
        try:
            out[key] = renderer.render(CAM, LENS).rgba.astype(np.float64)
            if key == "both":
                image = renderer.deep(CAM, LENS)
        finally:
            renderer.release()
    assert _db(image.flatten(), out["both"]) >= 50.0
    _check_tidy(image)
    h, w = CAM.height, CAM.width
    plane = np.array([*(0.5 * np.array(CG)), 0.5])
    at = lambda z: DeepFrame(np.ones((h, w), int), np.tile(plane, (h * w, 1)), np.full((h * w, 2), z))  # noqa: E731
    f, b = out["front"], out["back"]
    truth = f + (1.0 - f[..., 3:]) * (plane + (1.0 - plane[3]) * b)
    between = _db(image.merge(at(4.0)).flatten(), truth)
    in_front = _db(image.merge(at(0.5)).flatten(), truth)
    assert between >= 40.0 and in_front < between - 10.0
    # each sample lies wholly in front of the plane or behind it
    assert not np.any((image.depth[:, 0] < 4.0) & (image.depth[:, 1] > 4.0))


def test_tolerance_and_cap_merge_layers_and_keep_the_image(backend):
    front, back = _planes()
    renderer = backend(joined(front, back))
    try:
        flat = renderer.render(CAM, LENS).rgba
        fine = renderer.deep(CAM, LENS, deep=DeepSettings(1e-6, 64))
        one = renderer.deep(CAM, LENS, deep=DeepSettings(1e-6, 1))
        wide = renderer.deep(CAM, LENS, deep=DeepSettings(10.0, 64))
    finally:
        renderer.release()
    assert fine.counts.max() >= 2 and one.counts.max() == 1 and wide.counts.max() == 1
    for image in (fine, one, wide):
        assert _db(image.flatten(), flat) >= 50.0
        _check_tidy(image)


def test_cli_deep_with_the_default_settings_and_an_aperture(tmp_path, capsys):
    args = [str(SCENES.parent.parent / "samples" / "cards.ply"), "--width", "80", "--height", "60"]
    assert main(["render", *args, "--aperture", "200", "-o", str(tmp_path / "f.exr"),
                 "--deep", str(tmp_path / "d.exr")]) == 0
    counts, channels, header = read_deep_exr(tmp_path / "d.exr")  # the OpenEXR library reads it
    assert counts.shape == (60, 80) and counts.sum() == len(channels["ZBack"]) > 0
    assert json.loads(header["dofview:deep"]) == DeepSettings().to_dict()
    ch, _ = read_exr(tmp_path / "f.exr")
    flat = np.stack([ch[c] for c in "RGBA"], -1)
    image = DeepFrame.load(tmp_path / "d.exr")
    assert _db(image.flatten(), flat) >= 50.0


@pytest.mark.parametrize("colour_space", ["srgb", "linear"])
def test_sliced_deep_matches_the_cpu_twin(backend, colour_space):
    """Against rendering.reference.render_reference_sliced_deep (the CPU's float64 layers, blurred
    and composited by slices.sliced_image, captured the same way): 11 layers here, reduced ones
    among them (runs), the same sample counts, and the samples in front of every depth flatten
    alike (≥ 60 dB; measured 64–66 dB, as the flat frames agree at 66 dB with the highlight
    sprites, whose float32 sums differ from the twin's float64 ones; 90–100 dB before them); all
    of them to each side's own flat frame (≥ 50 dB)."""
    scene = random_scene(800, seed=6, colour_space=colour_space)
    scene.means[:, 2] = np.where(np.arange(800) % 2, 3.5, 7.0) + 0.8 * (scene.means[:, 2] - 5.0)
    camera, lens = look_at([0, 0, 0], [0, 0, 5], 64, 48, 60), Lens(7.0, 80.0)
    renderer = backend(scene)
    try:
        gpu = renderer.deep(camera, lens)
        flat = renderer.render(camera, lens).rgba
        layers = renderer.sliced_layers
    finally:
        renderer.release()
    assert len(layers) >= 6 and any(layer.scale > 1 for layer in layers)
    twin = render_reference_sliced_deep(scene, camera, lens)
    ref_flat = render_reference_sliced(scene, camera, lens).rgba
    assert _db(gpu.flatten(), flat) >= 50.0 and _db(twin.flatten(), ref_flat) >= 50.0
    assert (gpu.counts == twin.counts).mean() >= 0.99 and gpu.counts.max() >= 6
    _check_tidy(gpu)
    _check_tidy(twin)

    def in_front(image: DeepFrame, depth: float) -> np.ndarray:
        near = image.depth[:, 1] <= depth
        pixel = np.repeat(np.arange(image.counts.size), image.counts.ravel())
        return DeepFrame(np.bincount(pixel[near], minlength=image.counts.size).reshape(image.shape),
                         image.rgba[near], image.depth[near]).flatten()

    for depth in (3.0, 4.5, 6.0, 7.5, 20.0):
        assert _db(in_front(gpu, depth), in_front(twin, depth)) >= 60.0, depth
