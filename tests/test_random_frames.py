"""Random sliced frames against the twin: small random scenes (clouds, clouds with Gaussians at the
lens and far behind, large Gaussians, flat ones; half of them in linear light with a few bright
sources, which the sliced mode draws as highlight sprites), views, image sizes, lenses, blades and
τ, drawn by both backends as the whole lens or as one lens cell of a refinement stage, some as
deep images, each against rendering.reference (float64). A search over such frames found three
bugs the hand-made cases missed (a back layer prepared for the front's span of the order, the
twin's lens cells, the compute backend's faint coverage); the seeds below include theirs.

Tolerances: the linear image at 45 dB (peak max(1, brightest)), the depth within 1e-3 relative on
99 % of the pixels the twin covers (the compute backend stops a pixel at T < 1e-4 as the reference
3DGS rasteriser does, so where Gaussians 100× farther lie behind an opaque one its depth is held
where the twin's coverage is below 0.999); deep samples tidy, flattening to the GL frame at 50 dB
and to the twin's deep image at 45 dB.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import psnr, random_scene

from dofview.camera import look_at
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering import get_backend
from dofview.rendering.progressive import lens_cells
from dofview.rendering.reference import render_reference_sliced, render_reference_sliced_deep
from dofview.scene import SH_C0

# 135: three layers, the middle one beyond the frame's reach; 5141: a lens cell with a front layer
# drawn per splat; 1133: faint coverage on the compute backend; then seeds 0–59
SEEDS = [135, 5141, 1133, *range(60)]


def random_frame(seed: int):
    """(scene, camera, lens, settings, cell or None, deep) of one random frame."""
    rng = np.random.default_rng(seed)
    kind = rng.integers(0, 4)
    n = int(rng.integers(1, 400))
    scene = random_scene(n, degree=int(rng.choice([0, 1])), seed=seed, colour_space=str(rng.choice(["srgb", "linear"])))
    if kind == 1:  # some at the lens, some 4–40× farther than the cloud
        scene.means[: n // 3, 2] = rng.uniform(0.05, 0.6, n // 3)
        scene.means[n // 3: n // 2, 2] = rng.uniform(20, 200, n // 2 - n // 3)
    elif kind == 2:  # large
        scene.scales *= np.exp(rng.uniform(0, 3, (n, 1)))
    elif kind == 3:  # flat
        scene.scales[:, int(rng.integers(0, 3))] = 1e-6
    w, h = int(rng.integers(8, 120)), int(rng.integers(8, 100))
    cam = look_at(rng.normal(size=3) * 0.3, [rng.normal() * 0.3, rng.normal() * 0.3, 5], w, h, float(rng.uniform(20, 100)))
    focus = float(np.exp(rng.uniform(np.log(0.3), np.log(50))))
    lens = Lens(focus, float(np.exp(rng.uniform(np.log(0.5), np.log(2000)))) * (w / 100))
    settings = RenderSettings(dof="sliced", blades=int(rng.choice([0, 0, 5, 6])), blade_rotation=float(rng.uniform(0, 90)),
                              tau=float(rng.choice([0.0, 1 / 255, 2 / 255])))
    cell = None
    if rng.random() < 0.4:  # one pass of a refinement stage: its cell, seen from the cell's centroid
        cells = lens_cells(int(rng.choice([2, 4, 8, 16])), settings.blades, math.radians(settings.blade_rotation))
        cell = cells[int(rng.integers(0, len(cells)))]
        u, v = cell.point * 0.5 * lens.diameter(cam.fx)
        cam = cam.lens_shifted(float(u), float(v), lens.focus)
    deep = cell is None and rng.random() < 0.3
    light = np.random.default_rng(seed + 1_000_003)  # drawn apart, so that the shapes above keep their seeds
    if light.random() < 0.5:  # linear light with a few small sources of 10–1e4 (highlight sprites)
        scene.colour_space = "linear"
        k = max(1, n // 20)
        radiance = np.exp(light.uniform(math.log(10.0), math.log(1e4), (k, 1))) * light.uniform(0.3, 1.0, (k, 3))
        scene.sh_dc[:k] = (radiance - 0.5) / SH_C0
        scene.scales[:k] *= light.uniform(0.05, 0.5, (k, 1))
        scene.opacities[:k] = light.uniform(0.5, 1.0, k)
    return scene, cam, lens, settings, cell, deep


def _tidy(image) -> bool:
    z, back = image.depth[:, 0], image.depth[:, 1]
    pixel = np.repeat(np.arange(image.counts.size), image.counts.ravel())
    same = pixel[1:] == pixel[:-1]
    return bool(np.all(back >= z) and np.all(z[1:][same] >= back[:-1][same])
                and np.all((image.rgba[:, 3] >= 0) & (image.rgba[:, 3] <= 1 + 1e-6)))


@pytest.mark.parametrize("backend", ["quad", "compute"])
@pytest.mark.parametrize("seed", SEEDS)
def test_random_sliced_frames_match_the_twin(backend, seed):
    scene, cam, lens, settings, cell, deep = random_frame(seed)
    ref = render_reference_sliced(scene, cam, lens, settings, cell=cell)
    r = get_backend(backend, scene, packed=False)
    try:
        r.draw(cam, lens, settings, cell=cell)
        gl = r.read()
        image = r.deep(cam, lens, settings) if deep else None
    finally:
        r.release()
    assert np.isfinite(gl.rgba).all() and np.isfinite(gl.depth).all()
    peak = max(float(ref.rgba.max()), 1.0)
    assert psnr(gl.rgba, ref.rgba, peak) >= 45.0
    held = ref.depth > 0
    if backend == "compute":
        held &= ref.alpha < 0.999
    if held.any():
        assert np.mean(np.abs(gl.depth[held] - ref.depth[held]) <= 1e-3 * ref.depth[held]) >= 0.99
    if image is not None:
        assert _tidy(image) and np.isfinite(image.rgba).all()
        assert psnr(image.flatten(), gl.rgba, peak) >= 50.0
        assert psnr(image.flatten(), render_reference_sliced_deep(scene, cam, lens, settings).flatten(), peak) >= 45.0


if __name__ == "__main__":  # a longer search: python tests/test_random_frames.py FIRST END
    import sys

    failed = 0
    for seed in range(int(sys.argv[1]), int(sys.argv[2])):
        for backend in ("quad", "compute"):
            try:
                test_random_sliced_frames_match_the_twin(backend, seed)
            except AssertionError as e:
                failed += 1
                print(f"seed {seed} {backend}: {str(e).splitlines()[0] if str(e) else 'assertion failed'}", flush=True)
    print(f"seeds {sys.argv[1]}–{int(sys.argv[2]) - 1}: {failed} failed")
    sys.exit(1 if failed else 0)
