import numpy as np
import pytest

from dofview.scene import GaussianScene


def psnr(a: np.ndarray, b: np.ndarray, peak: float = 1.0) -> float:
    mse = float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(peak * peak / mse)


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


@pytest.fixture
def small_scene() -> GaussianScene:
    return random_scene()
