"""The trainable HDR Gaussian scene: raw parameters, their activations, initialisation, export.

The base colour c (the SH degree-0 term) is stored as a logarithm, so radiance is positive and
unbounded above (a lamp 1000× brighter than a wall is as easy to represent as the wall). View
dependence (SH degrees 1..3, ``sh_rest``) is stored relative to c: the colour seen along d is
c·max(1 + Σ Y_j(d)·r_j, 0) — exactly a standard file's max(SH_C0·f_dc + 0.5 + Σ Y_j·f_rest_j, 0)
with f_rest = c·r, so the export is exact, and one learning rate fits a wall and a lamp alike.
Opacity is a logit, scales are logs, rotations unnormalised quaternions — as in 3DGS.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import torch

from dofview.scene import SH_C0, ColourSpace, GaussianScene
from dofview.train.dataset import Dataset
from dofview.train.losses import DARK, SATURATED
from dofview.train.points import nearest_distance

PARAMS = ("means", "log_scales", "quats", "opacity_logits", "log_colours", "sh_rest")
MIN_COLOUR = 1e-4  # a floor for the log of an initial colour (black pixels)
RANDOM_OPACITY = 0.3
POINTS_OPACITY = 0.1  # the reference 3DGS start's: SfM points lie dense on the surfaces
PIXELS_PER_RANDOM = 16  # the default random start: one Gaussian per this many pixels of a photo


class GaussianModel:
    """Raw parameters as leaf tensors in :attr:`params` (name → (N, …) float32 tensor)."""

    def __init__(self, params: dict[str, torch.Tensor]) -> None:
        params = dict(params)
        if "sh_rest" not in params:  # a degree-0 model (and checkpoints from before SH)
            params["sh_rest"] = params["means"].new_zeros(len(params["means"]), 0, 3)
        self.params = {k: params[k].detach().clone().requires_grad_(True) for k in PARAMS}

    @property
    def count(self) -> int:
        return int(self.params["means"].shape[0])

    @property
    def sh_degree(self) -> int:
        """The SH degree the model stores (0..3)."""
        return {0: 0, 3: 1, 8: 2, 15: 3}[int(self.params["sh_rest"].shape[1])]

    def view_sh(self, colours: torch.Tensor, degree: int) -> torch.Tensor | None:
        """(N, (degree+1)² − 1, 3) absolute SH coefficients c·r of degrees 1..``degree`` (the active
        bands: the others get no gradient), or None at degree 0; ``colours`` (N, 3) from :meth:`activated`."""
        k = (min(degree, self.sh_degree) + 1) ** 2 - 1
        return colours[:, None, :] * self.params["sh_rest"][:, :k] if k else None

    def activated(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """(means (N, 3), quats (N, 4), scales (N, 3), opacities (N,), colours (N, 3))."""
        p = self.params
        return (p["means"], p["quats"], torch.exp(p["log_scales"]), torch.sigmoid(p["opacity_logits"]),
                torch.exp(p["log_colours"]))

    def to_scene(self, colour_space: ColourSpace, name: str = "trained") -> GaussianScene:
        """Export at the stored SH degree: SH_C0·dc + 0.5 = c and f_rest = c·r reproduce the trained
        colour in every dofview renderer (and the Inria file layout)."""
        with torch.no_grad():
            act = self.activated()
            sh = self.view_sh(act[4], self.sh_degree)
            means, quats, scales, opacities, colours = (t.detach().cpu().double().numpy() for t in act)
        quats = quats / np.maximum(np.linalg.norm(quats, axis=1, keepdims=True), 1e-12)
        return GaussianScene(means=means, quats=quats, scales=scales, opacities=opacities,
                             sh_dc=(colours - 0.5) / SH_C0, colour_space=colour_space, name=name,
                             sh_rest=None if sh is None else sh.detach().cpu().numpy())

    def state(self) -> dict[str, torch.Tensor]:
        return {k: v.detach().cpu() for k, v in self.params.items()}


def random_start_count(dataset: Dataset, max_count: int | None = None) -> int:
    """The default size of a random start: one Gaussian per :data:`PIXELS_PER_RANDOM` pixels of
    the average photo, at most ``max_count``."""
    pixels = np.mean([s.camera.width * s.camera.height for s in dataset.shots])
    count = max(1, round(pixels / PIXELS_PER_RANDOM))
    return count if max_count is None else min(count, max_count)


def initial_model(dataset: Dataset, photos: list[np.ndarray], count: int | None, linear: bool,
                  rng: np.random.Generator, device: torch.device, sh_degree: int = 0,
                  max_count: int | None = None) -> GaussianModel:
    """The Gaussians a fit starts from, view-independent at first (SH bands 1..``sh_degree`` zero):
    the dataset's SfM points when it has them (:func:`points_start`, at most ``max_count``), else
    ``count`` random ones (:func:`random_start`; None: :func:`random_start_count`)."""
    if dataset.points is not None:
        means, colours, sizes = points_start(dataset, photos, linear, rng, max_count)
        opacity = POINTS_OPACITY
    else:
        count = random_start_count(dataset, max_count) if count is None else count
        means, colours, sizes = random_start(dataset, photos, count, linear, rng)
        opacity = RANDOM_OPACITY
    n = len(means)
    quats = np.zeros((n, 4))
    quats[:, 0] = 1.0
    f = lambda a: torch.tensor(a, dtype=torch.float32, device=device)  # noqa: E731
    return GaussianModel({
        "means": f(means),
        "log_scales": f(np.log(np.repeat(sizes[:, None], 3, axis=1))),
        "quats": f(quats),
        "opacity_logits": f(np.full(n, math.log(opacity / (1 - opacity)))),
        "log_colours": f(np.log(np.maximum(colours, MIN_COLOUR))),
        "sh_rest": f(np.zeros((n, (sh_degree + 1) ** 2 - 1, 3))),
    })


def random_start(dataset: Dataset, photos: list[np.ndarray], count: int, linear: bool,
                 rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``count`` random points of the training cameras' frusta: (means (count, 3) scene units,
    colours (count, 3), sizes (count,) scene units).

    Each point is a random pixel of a random photo, pushed out to a depth drawn uniformly in
    inverse depth over the dataset's depth range (:meth:`Dataset.scene_depths`: ½× the nearest
    to 2× the farthest focus distance, unless the file gives one). Its colour is that pixel's
    value — for an HDR model un-exposed to radiance, pixel^γ / (t/N²) — and its size about one
    pixel's footprint at that depth. Nothing comes from the scene the photos were made of.
    """
    near, far = dataset.scene_depths()
    pick = rng.integers(0, len(dataset.shots), count)
    means, colours, sizes = np.empty((count, 3)), np.empty((count, 3)), np.empty(count)
    inv = rng.uniform(1.0 / far, 1.0 / near, count)
    for j, (i, inv_z) in enumerate(zip(pick, inv)):
        shot, photo = dataset.shots[i], photos[i]
        cam = shot.camera
        px, py = rng.uniform(0, cam.width), rng.uniform(0, cam.height)
        z = 1.0 / inv_z
        means[j] = cam.centre + z * cam.pixel_ray(px, py)
        value = photo[int(py), int(px)].astype(np.float64)
        colours[j] = value ** dataset.gamma / shot.exposure if linear else value
        sizes[j] = 1.5 * z / cam.fx
    return means, colours, sizes


def points_start(dataset: Dataset, photos: list[np.ndarray], linear: bool, rng: np.random.Generator,
                 max_count: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The dataset's SfM points (a random ``max_count`` of them when there are more), as the
    reference 3DGS starts: (means (P, 3) scene units, colours (P, 3), sizes (P,) scene units).

    The size is the RMS distance to the 3 nearest other points. The colour is seen in the photos,
    as the random start's: the median, over the photos in whose frame the point lies (in front
    of the camera), of the pixel it lands on — un-exposed to radiance, pixel^γ / (t/N²), for an
    HDR model, with pixels black or saturated in any channel left out (they carry no radiance);
    occlusion is not modelled, the median outvotes it. A point no photo shows usefully takes the
    file's colour at the key exposure (mid-grey when the file has none).
    """
    points = dataset.points
    assert points is not None
    keep = np.arange(len(points.positions))
    if max_count is not None and len(keep) > max_count:
        keep = np.sort(rng.choice(keep, max_count, replace=False))
    means = points.positions[keep]
    samples = np.full((len(photos), len(means), 3), np.nan, np.float32)
    for i, (shot, photo) in enumerate(zip(dataset.shots, photos)):
        cam = shot.camera
        t = cam.world_to_camera(means)
        front = t[:, 2] > 0
        z = np.where(front, t[:, 2], 1.0)
        px, py = cam.fx * t[:, 0] / z + cam.cx, cam.fy * t[:, 1] / z + cam.cy
        seen = np.nonzero(front & (px >= 0) & (px < cam.width) & (py >= 0) & (py < cam.height))[0]
        value = photo[py[seen].astype(int), px[seen].astype(int)]
        if linear:
            ok = ((value > DARK) & (value < SATURATED)).all(1)
            seen, value = seen[ok], value[ok] ** dataset.gamma / shot.exposure
        samples[i, seen] = value
    with warnings.catch_warnings():  # a point no photo shows has an all-NaN column: handled below
        warnings.simplefilter("ignore", RuntimeWarning)
        colours = np.nanmedian(samples, axis=0).astype(np.float64)
    own = np.full((len(means), 3), 0.5) if points.colours is None else points.colours[keep].astype(np.float64)
    own = own ** dataset.gamma / dataset.key_exposure() if linear else own
    colours = np.where(np.isnan(colours), own, colours)
    if len(means) > 1:
        return means, colours, nearest_distance(means)
    cam = dataset.shots[0].camera  # a lone point has no neighbours: the random start's size, a pixel and a half
    return means, colours, np.array([1.5 * np.linalg.norm(means[0] - cam.centre) / cam.fx])
