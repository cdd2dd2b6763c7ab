import numpy as np
import pytest

from dofview.bench.metrics import psnr  # noqa: F401  (tests import it from here
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


@pytest.fixture
def small_scene() -> GaussianScene:
    return random_scene()
