import numpy as np
import pytest

from dofview.bench.metrics import psnr  # noqa: F401  (tests import it from here
from dofview.rendering import BACKENDS, backend_class
from dofview.scene import GaussianScene


def random_scene(n: int = 1500, degree: int = 0, seed: int = 0, colour_space: str = "srgb") -> GaussianScene:
    """A small cloud of anisotropic Gaussians around z = 5 (camera at the origin looking +z)."""
    rng = np.random.default_rng(seed)
    rest = rng.normal(size=(n, (degree + 1) ** 2 - 1, 3)) * 0.15 if degree else None
    return GaussianScene(
        means=rng.uniform(-1, 1, (n, 3)) * [1.6, 1.2, 2.5] + [0, 0, 5],
        quats=rng.normal(size=(n, 4)),
        scales=np.exp(rng.uniform(-4.5, -1.8, (n, 3))),
        opacities=rng.uniform(0.05, 1.0, n),
        sh_dc=rng.normal(size=(n, 3)),
        sh_rest=rest,
        colour_space=colour_space,
    )


def mutate_bytes(data, base: bytes, kinds=("flip", "cut", "insert", "delete", "digit", "word")) -> bytes:
    """1–4 mutations of ``base`` drawn with hypothesis ``data``: byte flips, cuts, insertions,
    deletions, ASCII digits changed (header counts) and 32-bit words overwritten (binary counts
    and sizes)."""
    from hypothesis import strategies as st

    b = bytearray(base)
    for _ in range(data.draw(st.integers(1, 4))):
        kind = data.draw(st.sampled_from(kinds))
        pos = data.draw(st.integers(0, max(len(b) - 1, 0)))
        if kind == "flip" and b:
            b[pos] = data.draw(st.integers(0, 255))
        elif kind == "cut":
            del b[pos:]
        elif kind == "insert":
            b[pos:pos] = data.draw(st.binary(min_size=1, max_size=16))
        elif kind == "delete":
            del b[pos:pos + data.draw(st.integers(1, 16))]
        elif kind == "digit":  # numbers in the header (counts) and ASCII bodies
            digits = [i for i, c in enumerate(b) if 0x30 <= c <= 0x39]
            if digits:
                b[data.draw(st.sampled_from(digits))] = data.draw(st.sampled_from(b"0123456789-.e"))
        elif kind == "word" and len(b) >= 4:
            pos = min(pos, len(b) - 4)
            b[pos:pos + 4] = data.draw(st.sampled_from([0, 1, 255, 2**16, 2**31, 2**32 - 1])).to_bytes(4, "little")
    return bytes(b)


def assert_valid_scene(scene: GaussianScene) -> None:
    """What every reader promises of a scene it returns: matching counts, finite values, positive
    scales, opacities in [0, 1], unit quaternions (the fuzz tests' check)."""
    assert isinstance(scene, GaussianScene)
    n = scene.count
    for a in (scene.means, scene.scales, scene.quats, scene.opacities, scene.sh_dc):
        assert a.shape[0] == n and np.isfinite(a).all()
    assert scene.sh_rest is None or np.isfinite(scene.sh_rest).all()
    assert np.all(scene.scales > 0) and np.all((scene.opacities >= 0) & (scene.opacities <= 1))
    np.testing.assert_allclose(np.linalg.norm(scene.quats, axis=1), 1.0, atol=1e-5)


def assert_matches_reference(gl, reference, min_psnr=45.0, depth_rtol=1e-3, max_near_cut=0.005):
    """Linear image PSNR ≥ 45 dB (peak: max(1, brightest reference value)) and depth within 1e-3
    relative where the reference α > 0.5. Pixels where a contribution sits within 1e-5 of the τ
    cut (a float32/float64 coin flip) are left out of the depth check; they must stay rare
    (``max_near_cut`` of the image; dense scenes blurred with τ = 0 put many 3σ edges near pixels)."""
    ref, near_cut = reference
    assert np.all(np.isfinite(gl.rgba)) and np.all(np.isfinite(gl.depth))
    peak = max(float(ref.rgba.max()), 1.0)
    assert psnr(gl.rgba, ref.rgba, peak) >= min_psnr
    assert near_cut.mean() <= max_near_cut
    covered = (ref.alpha > 0.5) & ~near_cut
    assert covered.any()
    rel = np.abs(gl.depth[covered] - ref.depth[covered]) / ref.depth[covered]
    assert rel.max() <= depth_rtol


def assert_matches_sliced_reference(gl, ref, min_psnr=45.0, depth_rtol=1e-3):
    """The sliced mode against rendering.reference.render_reference_sliced: linear image PSNR ≥
    45 dB (peak as assert_matches_reference) and depth within 1e-3 relative on 99 % of the pixels
    the reference has a depth for (the sliced mode's depth is its layers' pinhole depth, drawn
    wherever the pinhole drew; the reference marks no near-cut pixels for it, where a float32 coin
    flip at a cut can land elsewhere)."""
    assert np.all(np.isfinite(gl.rgba)) and np.all(np.isfinite(gl.depth))
    peak = max(float(ref.rgba.max()), 1.0)
    assert psnr(gl.rgba, ref.rgba, peak) >= min_psnr
    covered = ref.depth > 0
    if covered.any():
        rel = np.abs(gl.depth[covered] - ref.depth[covered]) / ref.depth[covered]
        assert np.mean(rel <= depth_rtol) >= 0.99


@pytest.fixture
def small_scene() -> GaussianScene:
    return random_scene()


@pytest.fixture(params=sorted(BACKENDS))
def backend(request):
    """Each renderer backend's class (dofview.rendering.BACKENDS), for the tests every backend must pass."""
    return backend_class(request.param)
