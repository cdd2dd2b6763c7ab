"""Packed GPU storage: exact round trip of what must be exact, and image error vs float32 storage."""

import numpy as np
import pytest
from conftest import psnr, random_scene

from dofview.camera import look_at
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering.packing import pack_core
from dofview.rendering.quad import QuadBackend

CAM = look_at([0.2, -0.1, 0.0], [0.0, 0.0, 5.0], 160, 120, 60)


def unpack_core(words):
    """numpy mirror of rendering/glsl/fetch_packed.glsl, for checking the packer itself."""
    mean = words[:, :3].view(np.float32)
    halves = lambda w: (w & 0xFFFF).astype(np.uint16).view(np.float16).astype(np.float32)
    scale = np.stack([halves(words[:, 3]), halves(words[:, 3] >> 16), halves(words[:, 4])], 1)
    base = np.stack([halves(words[:, 4] >> 16), halves(words[:, 5]), halves(words[:, 5] >> 16)], 1)
    sn = lambda w: np.maximum((w & 0xFFFF).astype(np.uint16).view(np.int16) / 32767.0, -1.0)
    rest = np.stack([sn(words[:, 6]), sn(words[:, 6] >> 16), sn(words[:, 7])], 1) / np.sqrt(2)
    largest = (words[:, 7] >> 16) & 3
    big = np.sqrt(np.maximum(1 - (rest**2).sum(1), 0))
    q = np.zeros((len(words), 4))
    for i in range(len(words)):
        q[i] = np.insert(rest[i], largest[i], big[i])
    opacity = (words[:, 7] >> 18) / 16383.0
    return mean, scale, base, q, opacity


def test_pack_core_round_trip_precision():
    scene = random_scene(n=3000, seed=9)
    mean, scale, base, q, opacity = unpack_core(pack_core(scene))
    np.testing.assert_array_equal(mean, scene.means)
    np.testing.assert_allclose(scale, scene.scales, rtol=2**-11)
    np.testing.assert_allclose(base, 0.28209479177387814 * scene.sh_dc + 0.5, rtol=2**-11, atol=1e-7)
    qt = scene.unit_quats()
    same = np.minimum(np.abs(q - qt).max(1), np.abs(q + qt).max(1))  # q and −q are one rotation
    assert same.max() < 5e-5
    np.testing.assert_allclose(opacity, scene.opacities, atol=0.5 / 16383 + 1e-7)


@pytest.mark.parametrize("degree", [0, 3])
@pytest.mark.parametrize("aperture", [0.0, 60.0])
def test_packed_image_error_against_float32_storage(degree, aperture):
    """Issue 7: the packing's image error, PSNR ≥ 50 dB against full precision."""
    scene = random_scene(n=4000, degree=degree, seed=degree + 20)
    lens, settings = Lens(4.5, aperture), RenderSettings()
    full = QuadBackend(scene, packed=False).render(CAM, lens, settings)
    packed = QuadBackend(scene, packed=True).render(CAM, lens, settings)
    assert psnr(packed.rgba, full.rgba) >= 50.0
