"""The trainer's photo model and losses (dofview/train/losses.py): gamma encoding at black, the
censored warm-up loss, and the trainer's forward model + tonemap against make-dataset's photos."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from dofview.rendering.reference import sh_colour  # noqa: E402
from dofview.train.dataset import load_dataset, load_photo  # noqa: E402
from dofview.train.generate import Capture, generate  # noqa: E402
from dofview.train.losses import GAMMA_TOE, aligned_loss, encode, tonemap  # noqa: E402
from dofview.train.native import rasterise_native  # noqa: E402
from dofview.train.optimise import TRAIN_RENDER  # noqa: E402


def test_encode_is_the_power_above_the_toe_and_zero_at_black():
    x = torch.tensor([0.0, 0.1 * GAMMA_TOE, 0.5 * GAMMA_TOE, GAMMA_TOE, 2 * GAMMA_TOE, 1e-3, 0.18, 1.0], dtype=torch.float64,
                     requires_grad=True)
    y = encode(x, 2.2)
    assert float(y.detach()[0]) == 0.0  # black stays black: no offset for SSIM or a mean to see
    above = x.detach() >= GAMMA_TOE
    assert torch.equal(y.detach()[above], x.detach()[above] ** (1 / 2.2))
    assert torch.all(torch.diff(y.detach()) > 0)
    y.sum().backward()
    assert torch.isfinite(x.grad).all() and float(x.grad[0]) == pytest.approx(GAMMA_TOE ** (1 / 2.2 - 1))


def test_warm_up_loss_reads_black_and_saturated_pixels_as_bounds():
    """A black pixel says 'darker than half a step': a render below that costs nothing, above it
    costs; a saturated pixel says the opposite; other pixels are compared as values."""
    exposure, key, gamma = 4.0, 1.0, 2.2
    photo = torch.tensor([[[0.0, 1.0, 0.5]]])

    def loss(radiance):
        hdr = torch.tensor([[radiance]], dtype=torch.float32, requires_grad=True)
        value = aligned_loss(hdr, photo, exposure, key, gamma)
        value.backward()
        return float(value.detach()), hdr.grad[0, 0].tolist()

    bound = (0.5 / 255) ** gamma / exposure  # the black pixel's largest radiance
    sat = (254.5 / 255) ** gamma / exposure  # the saturated pixel's smallest
    mid = 0.5 ** gamma / exposure
    value, grad = loss([0.5 * bound, 2.0 * sat, mid])
    assert value == pytest.approx(0.0, abs=1e-7) and grad[0] == 0.0 and grad[1] == 0.0
    value, grad = loss([2.0 * bound, 0.5 * sat, 1.1 * mid])
    assert value > 0 and grad[0] > 0 and grad[1] < 0 and grad[2] > 0


def test_trainer_forward_model_reproduces_make_dataset_photos(tmp_path):
    """The true scene through the trainer's rasteriser, each photo's lens and Eq. 7 gives the photos
    make-dataset wrote with the GL renderer, to within their 8-bit rounding: the fit has no bias
    to learn (with a τ cut in the photos alone, faint regions were several steps darker)."""
    from test_train import hdr_scene

    scene = hdr_scene()
    generate(scene, tmp_path / "ds", Capture(views=6, held_out=0, width=64, height=48), eye=(0, 0, 0),
             target=(0, 0, 4.5), progress=False)
    ds = load_dataset(tmp_path / "ds")
    f = lambda a: torch.tensor(np.asarray(a, np.float32))  # noqa: E731
    for shot, lens in zip(ds.shots, ds.lenses()):
        colours = f(sh_colour(scene, shot.camera.centre, np.arange(scene.count)))
        with torch.no_grad():
            r = rasterise_native(f(scene.means), f(scene.quats), f(scene.scales), f(scene.opacities), colours,
                                 shot.camera, lens, TRAIN_RENDER)
        diff = (tonemap(r.rgb, shot.exposure, ds.gamma).numpy() - load_photo(shot)) * 255
        assert abs(float(diff.mean())) < 0.05 and float(np.abs(diff).mean()) < 0.3
        # the two rasterisers agree to ≥ 40 dB, not bit for bit: at the 3σ cut of the lamp's splats
        # α is still ~0.01, times a radiance of 100, so a pixel whose q rounds to the other side of 9
        # differs by up to 148/255 (measured: one such pixel in 3 of the 6 photos)
        assert float(np.mean(np.abs(diff) > 1.01)) <= 2 / diff.size * 3
