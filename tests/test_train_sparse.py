"""The trainer's sparse rasterisers (torch: dofview/train/sparse.py; C: dofview/train/native.py)
against the dense one and the GL renderer."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from conftest import psnr, random_scene  # noqa: E402

from dofview.camera import look_at  # noqa: E402
from dofview.cli import main  # noqa: E402
from dofview.frame import RenderSettings  # noqa: E402
from dofview.io import load_scene  # noqa: E402
from dofview.lens import Lens  # noqa: E402
from dofview.rendering.quad import QuadBackend  # noqa: E402
from dofview.rendering.reference import sh_colour  # noqa: E402
from dofview.train.native import rasterise_native  # noqa: E402
from dofview.train.raster import project, rasterise  # noqa: E402
from dofview.train.sparse import EARLY_STOP, bin_tiles, rasterise_sparse  # noqa: E402

# the native one builds with the system C compiler (tests/test_train_native.py: its fallback)
SPARSE = pytest.mark.parametrize("raster", [rasterise_sparse, rasterise_native], ids=["sparse", "native"])

CAM = look_at((0.3, 0.1, 0.0), (0.0, 0.0, 5.0), 64, 48, 60.0)


def _tensors(arrays, dtype=torch.float32, grad=False):
    return [torch.tensor(np.asarray(a), dtype=dtype, requires_grad=grad) for a in arrays]


@SPARSE
@pytest.mark.parametrize("aperture", [0.0, 20.0])
@pytest.mark.parametrize("settings", [RenderSettings(dof="splat"), RenderSettings(tau=0.0, dof="splat")])
def test_sparse_forward_matches_dense_and_gl(raster, aperture, settings):
    scene = random_scene(400, colour_space="linear")
    lens = Lens(focus=4.0, aperture=aperture)
    colours = sh_colour(scene, CAM.centre, np.arange(scene.count))
    args = _tensors((scene.means, scene.quats, scene.scales, scene.opacities, colours))
    # sparse: several chunks; native: several threads
    extra = {"budget": 3000} if raster is rasterise_sparse else {"threads": 3}
    sparse = raster(*args, CAM, lens, settings, **extra)
    dense = rasterise(*args, CAM, lens, settings)
    gl = QuadBackend(scene).render(CAM, lens, settings)
    peak = max(float(gl.rgba.max()), 1.0)
    assert psnr(sparse.rgb.numpy(), dense.rgb.numpy(), peak) >= 50.0
    assert psnr(sparse.alpha.numpy(), dense.alpha.numpy()) >= 50.0
    assert psnr(sparse.rgb.numpy(), gl.rgba[..., :3], peak) >= 40.0
    assert psnr(sparse.alpha.numpy(), gl.alpha) >= 40.0
    assert torch.equal(sparse.drawn, dense.drawn)


def _render_grads(raster, arrays, lens, settings):
    """(rgb, alpha, gradients of a weighted sum of rgb and alpha w.r.t. every parameter), float64."""
    params = _tensors(arrays, torch.float64, grad=True)
    r = raster(*params, CAM, lens, settings, retain_mean2d=True)
    g = torch.Generator().manual_seed(3)
    w_rgb = torch.rand(r.rgb.shape, generator=g, dtype=torch.float64)
    w_alpha = torch.rand(r.alpha.shape, generator=g, dtype=torch.float64)
    ((r.rgb * w_rgb).sum() + (r.alpha * w_alpha).sum()).backward()
    return r.rgb.detach(), r.alpha.detach(), [p.grad for p in params] + [r.mean2d.grad]


def _overlapping_scene(n=60, seed=1):
    """Splats 1–6 px wide piled in the middle of the view (every pixel sees several), and one
    wide splat centred on the corner of four tiles (pixel (32, 16) of the 64×48 view)."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(3.0, 7.0, n)
    px, py = rng.uniform(16, 48, n), rng.uniform(8, 40, n)
    px[0], py[0], z[0] = 32.0, 16.0, 3.5
    means = np.stack([CAM.centre + d * CAM.pixel_ray(x, y) for x, y, d in zip(px, py, z)])
    scales = np.exp(rng.uniform(np.log(0.5), np.log(3.0), (n, 3))) * z[:, None] / CAM.fx
    scales[0] = 6.0 * z[0] / CAM.fx
    return means, rng.normal(size=(n, 4)), scales, rng.uniform(0.1, 0.9, n), rng.uniform(0.1, 3.0, (n, 3))


@SPARSE
@pytest.mark.parametrize("aperture", [0.0, 20.0])
def test_sparse_gradients_match_dense_autograd(raster, aperture):
    arrays = _overlapping_scene()
    lens, settings = Lens(4.0, aperture), RenderSettings(tau=0.0, dof="splat")
    s = project(*_tensors(arrays, torch.float64), CAM, lens, settings)
    tiles = bin_tiles(s.lo, s.hi, CAM.width, CAM.height)
    assert int((tiles.gauss == 0).sum()) >= 4  # the corner splat is in four tiles or more
    rgb_s, alpha_s, grads_s = _render_grads(raster, arrays, lens, settings)
    rgb_d, alpha_d, grads_d = _render_grads(rasterise, arrays, lens, settings)
    assert float(alpha_d.max()) < 1.0 - EARLY_STOP  # no early stop here: every pixel stays transparent enough
    assert float(alpha_d.max()) > 0.9  # but several splats deep
    assert torch.allclose(rgb_s, rgb_d, rtol=1e-9, atol=1e-12)
    assert torch.allclose(alpha_s, alpha_d, rtol=1e-9, atol=1e-12)
    for name, a, b in zip(("means", "quats", "scales", "opacities", "colours", "mean2d"), grads_s, grads_d):
        assert torch.allclose(a, b, rtol=1e-7, atol=1e-9 * float(b.abs().max())), name


def _stack_scene():
    """Four wide splats of opacity 0.97 on one line of sight at depths 3, 3.5, 4 and 5: after the
    third, T = 0.03³ < 10⁻⁴ in the middle, so early stop drops the rest there."""
    z = np.array([3.0, 3.5, 4.0, 5.0])
    means = np.stack([CAM.centre + d * CAM.pixel_ray(30.0, 22.0) for d in z])
    rng = np.random.default_rng(2)
    scales = (3.0 * z / CAM.fx)[:, None] * rng.uniform(0.6, 1.2, (4, 3))
    return means, rng.normal(size=(4, 4)), scales, np.full(4, 0.97), rng.uniform(0.2, 2.0, (4, 3))


@SPARSE
def test_early_stop_and_its_gradients(raster):
    arrays = _stack_scene()
    lens, settings = Lens(4.0, 0.0), RenderSettings(tau=0.0, dof="splat")
    rgb_s, alpha_s, grads_s = _render_grads(raster, arrays, lens, settings)
    rgb_d, alpha_d, grads_d = _render_grads(rasterise, arrays, lens, settings)
    stopped = alpha_d > 1.0 - EARLY_STOP
    assert int(stopped.sum()) >= 4 and float(alpha_s.max()) <= 1.0 - EARLY_STOP + 1e-12  # it stopped there
    # early stop leaves out the first splat that would take T below 10⁻⁴, and all behind it: their
    # weights sum to the T before it, < 10⁻⁴ / (1 − α) with α ≤ 0.97, times a radiance ≤ 2
    assert 0.0 < float((rgb_s - rgb_d).abs().max()) <= 2.0 * EARLY_STOP / 0.03
    assert torch.allclose(rgb_s[~stopped], rgb_d[~stopped], rtol=1e-9, atol=1e-12)  # elsewhere the same
    # the gradients differ by those contributions (over 1 − α in ∂C/∂α of the splats in front):
    # tolerance 0.5 % of each parameter's largest gradient (measured: ≤ 0.07 %, the opacities)
    for name, a, b in zip(("means", "quats", "scales", "opacities", "colours", "mean2d"), grads_s, grads_d):
        assert not torch.equal(a, b) or name == "colours"
        assert torch.allclose(a, b, rtol=0.0, atol=5e-3 * float(b.abs().max())), name


@SPARSE
def test_gradcheck_double_precision(raster):
    """Finite differences of the sparse renderer itself (with early stop active) on a tiny view."""
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 5.0), 20, 16, 60.0)
    means, quats, scales, opacities, colours = _stack_scene()
    means = np.stack([cam.centre + d * cam.pixel_ray(9.3, 7.6) for d in (3.0, 3.5, 4.0, 5.0)])
    scales = scales * 0.5
    params = _tensors((means, quats, scales, opacities, colours), torch.float64, grad=True)

    def render(*p):
        r = raster(*p, cam, Lens(4.0, 6.0), RenderSettings(tau=0.0, dof="splat"))
        assert float(r.alpha.detach().max()) <= 1.0 - EARLY_STOP + 1e-12
        return r.rgb, r.alpha

    dense = rasterise(*params, cam, Lens(4.0, 6.0), RenderSettings(tau=0.0, dof="splat"))
    assert float(dense.alpha.detach().max()) > 1.0 - EARLY_STOP  # the dense path would have gone on
    assert torch.autograd.gradcheck(render, params, eps=1e-6, atol=1e-5, rtol=1e-4)


def test_train_cli_every_rasteriser(tmp_path):
    """``dofview train --torch-raster`` takes each; each writes a linear scene."""
    from test_train import Capture, generate, hdr_scene

    ds = tmp_path / "ds"
    generate(hdr_scene(), ds, Capture(views=3, held_out=0, width=32, height=24), eye=(0, 0, 0),
             target=(0, 0, 4.5), progress=False)
    for raster in ("native", "sparse", "dense"):
        out = tmp_path / f"{raster}.ply"
        assert main(["train", str(ds), "-o", str(out), "--iterations", "12", "--warmup", "6", "--gaussians", "40",
                     "--checkpoint-every", "0", "--torch-raster", raster]) == 0
        assert load_scene(out, progress=False).count > 0
    with pytest.raises(SystemExit) as bad:  # argparse: an unknown choice is a usage error
        main(["train", str(ds), "-o", str(tmp_path / "x.ply"), "--torch-raster", "fast"])
    assert bad.value.code == 2 and not (tmp_path / "x.ply").exists()
