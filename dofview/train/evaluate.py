"""Score a trained scene on a dataset's held-out all-in-focus HDR views.

Each held-out view is rendered by dofview's GL renderer (pinhole, so all in focus) from the
written scene file, as ``dofview render --tau 0`` would (no τ cut: as the held-out views were made,
:data:`dofview.train.generate.PHOTO_RENDER`), with the trainer's near plane
(:meth:`Dataset.near_plane`). An HDR ("linear") scene's render is
radiance as it stands; an sRGB scene (the plain LDR fit) is decoded to linear and divided by the
dataset's key exposure (geometric mean of t/N²), the exposure its colours correspond to on
average.

Metrics, against the ground-truth EXR:
- log-radiance PSNR: 20·log10(peak / RMSE) of ln(max(x, floor)) over all pixels and channels,
  floor = 1e-4 × the view's brightest ground-truth value, peak = ln(max) − ln(floor);
- bright-region ratio: summed luminance of the rendered image over the pixels whose ground-truth
  luminance exceeds 10× the view's median, divided by the same sum of the ground truth (the
  light's recovered radiance; 1 is exact).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from dofview.errors import DofviewError
from dofview.io.exr import read_exr
from dofview.lens import Lens
from dofview.scene import GaussianScene
from dofview.train.dataset import Dataset
from dofview.train.generate import PHOTO_RENDER

LOG_FLOOR = 1e-4
BRIGHT = 10.0


@dataclass(frozen=True)
class Evaluation:
    """Per held-out view scores (lists in dataset order) and their means."""

    log_psnr: list[float]
    bright_ratio: list[float]

    @property
    def mean_log_psnr(self) -> float:
        return float(np.mean(self.log_psnr))

    @property
    def mean_bright_ratio(self) -> float:
        """Mean ratio over the views that see a bright region (nan when none does)."""
        return float(np.mean(self.bright_ratio)) if self.bright_ratio else math.nan


def log_psnr(pred: np.ndarray, truth: np.ndarray) -> float:
    """Log-radiance PSNR (dB) of two (H, W, 3) linear images (see the module docstring)."""
    top = float(truth.max())
    floor = LOG_FLOOR * top
    a = np.log(np.maximum(pred.astype(np.float64), floor))
    b = np.log(np.maximum(truth.astype(np.float64), floor))
    rmse = math.sqrt(float(np.mean((a - b) ** 2)))
    return math.inf if rmse == 0 else 20 * math.log10((math.log(top) - math.log(floor)) / rmse)


def bright_ratio(pred: np.ndarray, truth: np.ndarray) -> float | None:
    """Rendered / true luminance summed over the bright region, or None when there is none."""
    lum_t, lum_p = truth.mean(-1), pred.mean(-1)
    mask = lum_t > BRIGHT * np.median(lum_t)
    if not mask.any():
        return None
    return float(lum_p[mask].sum() / lum_t[mask].sum())


def render_radiance(scene: GaussianScene, dataset: Dataset, renderer) -> list[np.ndarray]:
    """(H, W, 3) float32 linear radiance of each held-out view, as the scene file renders it."""
    scale = 1.0 if scene.colour_space == "linear" else 1.0 / dataset.key_exposure()
    settings = replace(PHOTO_RENDER, near=dataset.near_plane())
    return [renderer.render(h.camera, Lens(1.0, 0.0), settings).rgba[..., :3] * scale for h in dataset.held_out]


def evaluate(scene: GaussianScene, dataset: Dataset, raster: str = "quad") -> Evaluation:
    """Scores of ``scene`` on ``dataset``'s held-out views (needs at least one), rendered by backend
    ``raster`` (:func:`dofview.rendering.get_backend`)."""
    from dofview.rendering import get_backend

    if not dataset.held_out:
        raise DofviewError(f"{dataset.root}: the dataset has no held-out views (split: test) to evaluate on")
    renderer = get_backend(raster, scene)
    try:
        preds = render_radiance(scene, dataset, renderer)
    finally:
        renderer.release()
    psnrs, ratios = [], []
    for view, pred in zip(dataset.held_out, preds):
        channels, _ = read_exr(view.hdr_path)
        truth = np.stack([channels[c] for c in "RGB"], -1)
        psnrs.append(log_psnr(pred, truth))
        r = bright_ratio(pred, truth)
        if r is not None:
            ratios.append(r)
    return Evaluation(psnrs, ratios)
