"""The training loop: Adam, coarse-to-fine, densification and pruning, checkpoints.

Stage 1 (``warmup`` steps): pinhole renders against exposure-aligned photos (no tonemapping, no
depth of field), which gives a first HDR point cloud. Stage 2: each render goes through the
photo's thin lens (Eq. 3–5) and its exposure and gamma (Eq. 7) and is scored by Eq. 8. Every
``densify_every`` steps Gaussians whose projected means had a large mean gradient (the mean's
shift measured in half image sizes, as the reference 3DGS measures it, so one threshold holds at
any resolution) are cloned (small ones) or split in two (those wider than a fraction of the image
width), and nearly transparent ones are pruned, so the model grows only where the photos ask for
it, up to ``max_gaussians``; the count is logged over time. The means' learning rate is relative
to the subject's distance (where the photos are focused) and falls exponentially over the run (as in the reference 3DGS), so
nothing depends on the scene's units. With ``sh_degree`` > 0
the colour turns view-dependent band by band, as the reference 3DGS trainer does (one SH degree
more every 1000 of its 30 000 steps, here every 1/30 of ``iterations``).

Variants (for the ablation): "full" (Eq. 8 as the paper has it), "no-exp" (λ_exp = 0), "no-foc"
(λ_foc = 0) and "ldr" — a plain 3DGS fit of the 8-bit photos as they are, ignoring exposure and
defocus (sRGB output). The default is "no-foc": with the Laplacian-energy stand-in for the paper's
blur detector, L_foc lowered the held-out score in every ablation run (docs/TRAINING.md).
"""

from __future__ import annotations

import math
import sys
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import torch

from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.io.atomic import atomic_output
from dofview.lens import Lens
from dofview.progress import Progress
from dofview.train.dataset import Dataset, load_photo
from dofview.train.evaluate import evaluate
from dofview.train.generate import PHOTO_RENDER
from dofview.train.losses import aligned_loss, delta, photo_loss, tonemap
from dofview.train.model import PARAMS, GaussianModel, initial_model
from dofview.train.raster import rotations
from dofview.train.rasterisers import RASTERISERS, choose_rasteriser

VARIANTS = ("full", "no-exp", "no-foc", "ldr")
DEFAULT_VARIANT = "no-foc"
# The trainer splats as the photos were taken: τ = 0 (3σ support; a τ cut would also hide faint
# Gaussians from the gradient) and the per-splat lens model it fits with.
TRAIN_RENDER = PHOTO_RENDER


@dataclass(frozen=True)
class TrainConfig:
    """Optimisation settings; learning rates are per step of Adam on the raw parameters.

    ``lr_means`` (random start) and ``lr_means_points`` (SfM start) are relative to the subject's
    distance (:meth:`Dataset.subject_distance`, scene units): not to the depth range, which a far
    background stretches (a tap 2 units away with a wall 90 units behind it).
    """

    iterations: int = 2000
    warmup: int = 500
    initial: int | None = None  # random start; None: sized to the photos (model.random_start_count)
    max_gaussians: int = 1500
    densify_every: int = 100
    densify_until: float = 0.8  # fraction of ``iterations``
    # mean |∂L/∂mean2d| over the views that draw a Gaussian, the mean's shift measured in half image
    # sizes (the reference 3DGS's NDC units and threshold): the same for any resolution and scene scale
    grad_threshold: float = 2e-4
    prune_opacity: float = 0.01
    split_fraction: float = 0.01  # Gaussians wider (largest σ) than this fraction of the image width are split
    lr_means: float = 3.2e-3  # from the random start: its points are off by up to the depth range
    # from SfM points, off by a pixel or so: the reference 3DGS's 1.6e-4 of its cameras' extent, which
    # was 1.6e-4 of the depth range here, ~1.6× the subject's distance on an object
    lr_means_points: float = 2.5e-4
    lr_means_decay: float = 0.01  # the means' rate falls exponentially to this fraction of it by the last step (3DGS: 0.01)
    lr_log_scales: float = 1e-2
    lr_quats: float = 2e-3
    lr_opacity: float = 5e-2
    lr_colours: float = 2e-2
    lr_sh: float = 1e-2  # of the SH bands relative to the base colour (dimensionless; docs/TRAINING.md)
    sh_degree: int = 0
    variant: str = DEFAULT_VARIANT
    seed: int = 0

    def __post_init__(self) -> None:
        if self.variant not in VARIANTS:
            raise DofviewError(f"variant must be one of {', '.join(VARIANTS)}, got {self.variant!r}")
        if self.iterations < 1 or (self.initial is not None and self.initial < 1) or self.warmup < 0:
            raise DofviewError("iterations and initial Gaussians must be ≥ 1, warm-up ≥ 0")
        if self.sh_degree not in (0, 1, 2, 3):
            raise DofviewError(f"--sh-degree must be 0, 1, 2 or 3, got {self.sh_degree}")

    def active_sh_degree(self, step: int) -> int:
        """The SH degree trained at ``step``: one more every ``iterations``/30 steps, up to ``sh_degree``."""
        return min(self.sh_degree, step // max(1, round(self.iterations / 30)))


@dataclass
class History:
    """What happened: every ``every`` steps step, stage, mean loss since the last record and
    Gaussian count (``rows``); at each checkpoint the held-out score (``scores``: step, mean
    log-radiance PSNR in dB and bright-region ratio on the dataset's held-out views)."""

    every: int = 50
    rows: list[dict] = field(default_factory=list)
    scores: list[dict] = field(default_factory=list)


def ndc_gradient(grad: torch.Tensor, camera: Camera) -> torch.Tensor:
    """(M,) the densification statistic of one view: |∂L/∂mean2d| with the shift measured in half
    image sizes (the reference 3DGS's NDC units), from ``grad`` (M, 2), ∂L per pixel of shift."""
    half = torch.tensor([camera.width / 2, camera.height / 2], dtype=grad.dtype, device=grad.device)
    return (grad * half).norm(dim=1)


def pick_device(name: str = "auto") -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise DofviewError("--device cuda: no CUDA device is available to torch")
    return torch.device(name)


class Trainer:
    """Fits a :class:`GaussianModel` to a :class:`Dataset` (see the module docstring)."""

    def __init__(self, dataset: Dataset, config: TrainConfig = TrainConfig(), device: str = "auto",
                 raster: str | None = None) -> None:
        self.dataset, self.config = dataset, config
        self.device = pick_device(device)
        self.raster = choose_rasteriser(raster, self.device)
        self.rasterise = RASTERISERS[self.raster]
        if self.device.type == "cpu":
            # The tensors are small: one thread is as fast, and several spin-wait badly (10–20×
            # slower steps) whenever another process holds a core.
            torch.set_num_threads(1)
        self.rng = np.random.default_rng(config.seed)
        torch.manual_seed(config.seed)
        photos = [load_photo(s) for s in dataset.shots]
        self.photos = [torch.tensor(p, device=self.device) for p in photos]
        self.lenses = dataset.lenses()
        self.key = dataset.key_exposure()
        self.subject = dataset.subject_distance()
        self.render = replace(TRAIN_RENDER, near=dataset.near_plane())
        self.linear = config.variant != "ldr"
        self.model = initial_model(dataset, photos, config.initial, self.linear, self.rng, self.device,
                                   config.sh_degree, config.max_gaussians)
        self.step = 0
        self.history = History()
        self.scoring = bool(dataset.held_out)  # off for good once the renderer is found missing
        self._new_optimiser()
        self._reset_stats()

    # ---- optimiser -------------------------------------------------------------------------
    def _lrs(self) -> dict[str, float]:
        c = self.config
        lr_means = c.lr_means_points if self.dataset.points is not None else c.lr_means
        return {"means": lr_means * self.subject, "log_scales": c.lr_log_scales, "quats": c.lr_quats,
                "opacity_logits": c.lr_opacity, "log_colours": c.lr_colours, "sh_rest": c.lr_sh}

    def _new_optimiser(self) -> None:
        lrs = self._lrs()
        self.optimiser = torch.optim.Adam(
            [{"params": [self.model.params[k]], "lr": lrs[k], "name": k} for k in PARAMS], eps=1e-15)

    def _reset_stats(self) -> None:
        n = self.model.count
        self.grad_sum = torch.zeros(n, device=self.device)
        self.grad_count = torch.zeros(n, device=self.device)

    # ---- one step --------------------------------------------------------------------------
    def loss(self, i: int) -> tuple[torch.Tensor, object]:
        """The loss of training photo ``i`` at the current stage, and the raster (for its mean2d)."""
        shot, photo = self.dataset.shots[i], self.photos[i]
        means, quats, scales, opacities, colours = self.model.activated()
        sh = self.model.view_sh(colours, self.config.active_sh_degree(self.step))
        warm = self.step < self.config.warmup
        if self.config.variant == "ldr" or warm:
            raster = self.rasterise(means, quats, scales, opacities, colours, shot.camera, Lens(1.0, 0.0),
                                    self.render, retain_mean2d=True, sh=sh)
            if self.config.variant == "ldr":
                return delta(raster.rgb, photo), raster
            return aligned_loss(raster.rgb, photo, shot.exposure, self.key, self.dataset.gamma), raster
        raster = self.rasterise(means, quats, scales, opacities, colours, shot.camera, self.lenses[i],
                                self.render, retain_mean2d=True, sh=sh)
        ldr = tonemap(raster.rgb, shot.exposure, self.dataset.gamma)
        loss, _ = photo_loss(ldr, photo, use_exp=self.config.variant != "no-exp",
                             use_foc=self.config.variant != "no-foc")
        return loss, raster

    def train_step(self) -> float:
        i = int(self.rng.integers(len(self.dataset.shots)))
        if self.config.warmup and self.step == self.config.warmup:
            self._new_optimiser()  # stage 2 starts with fresh moments: the loss changes scale
        decay = self.config.lr_means_decay ** (self.step / self.config.iterations)
        for group in self.optimiser.param_groups:
            if group["name"] == "means":
                group["lr"] = self._lrs()["means"] * decay
        loss, raster = self.loss(i)
        loss.backward()
        if raster.mean2d.grad is not None:
            self.grad_sum.index_add_(0, raster.drawn, ndc_gradient(raster.mean2d.grad, self.dataset.shots[i].camera))
            self.grad_count.index_add_(0, raster.drawn, torch.ones_like(raster.drawn, dtype=torch.float32))
        self.optimiser.step()
        self.optimiser.zero_grad(set_to_none=True)
        self.step += 1
        c = self.config
        if self.step % c.densify_every == 0 and self.step < c.densify_until * c.iterations:
            self.densify_and_prune()
        return float(loss.detach())

    # ---- densification ---------------------------------------------------------------------
    def densify_and_prune(self) -> None:
        """Clone or split where the mean screen-space gradient is large; prune near-transparent."""
        c, p = self.config, self.model.params
        with torch.no_grad():
            avg = self.grad_sum / self.grad_count.clamp(min=1)
            grow = torch.nonzero(avg > c.grad_threshold).squeeze(1)
            room = max(c.max_gaussians - self.model.count, 0)
            grow = grow[torch.argsort(avg[grow], descending=True)[:room]]
            # a Gaussian's width as a fraction of the image width, seen from the mean training camera
            depth = (p["means"][grow] - self._mean_centre()).norm(dim=1).clamp(min=1e-30)
            width = torch.exp(p["log_scales"][grow]).amax(1) / depth * self._fx_per_width()
            split, clone = grow[width > c.split_fraction], grow[width <= c.split_fraction]
            new = {k: [p[k][clone]] for k in PARAMS}
            for _ in range(2):  # each split Gaussian becomes two, sampled from itself, 1.6× smaller
                sample = torch.randn(len(split), 3, device=self.device) * torch.exp(p["log_scales"][split])
                new["means"].append(p["means"][split] + torch.einsum("nij,nj->ni", rotations(p["quats"][split]), sample))
                new["log_scales"].append(p["log_scales"][split] - math.log(1.6))
                for k in ("quats", "opacity_logits", "log_colours", "sh_rest"):
                    new[k].append(p[k][split])
            keep = torch.ones(self.model.count, dtype=torch.bool, device=self.device)
            keep[split] = False
            keep &= torch.sigmoid(p["opacity_logits"]) >= c.prune_opacity
            self._edit(keep, {k: torch.cat(v) for k, v in new.items()})
        self._reset_stats()

    def _mean_centre(self) -> torch.Tensor:
        centres = np.mean([s.camera.centre for s in self.dataset.shots], axis=0)
        return torch.tensor(centres, dtype=torch.float32, device=self.device)

    def _fx_per_width(self) -> float:
        """Mean f_x / image width of the training cameras (½ / tan of half the field of view)."""
        return float(np.mean([s.camera.fx / s.camera.width for s in self.dataset.shots]))

    def _edit(self, keep: torch.Tensor, new: dict[str, torch.Tensor]) -> None:
        """Keep rows ``keep`` of every parameter, append ``new``; Adam moments follow (zeros for new)."""
        for group in self.optimiser.param_groups:
            old = group["params"][0]
            name = group["name"]
            state = self.optimiser.state.pop(old, None)
            param = torch.cat([old.detach()[keep], new[name]]).requires_grad_(True)
            if state:
                for m in ("exp_avg", "exp_avg_sq"):
                    state[m] = torch.cat([state[m][keep], torch.zeros_like(new[name])])
                self.optimiser.state[param] = state
            group["params"][0] = param
            self.model.params[name] = param

    # ---- the loop, checkpoints -------------------------------------------------------------
    def run(self, progress: bool = True, checkpoint: Path | None = None, checkpoint_every: int = 0) -> GaussianModel:
        """Train to ``config.iterations`` steps (from wherever a resumed run stands); every
        ``checkpoint_every`` steps score the held-out views and write ``checkpoint``."""
        c = self.config
        total, seen = 0.0, 0
        score = ""
        with Progress(f"training ({c.variant}, {self.raster})", c.iterations, delay=0.5 if progress else 1e9,
                      resumed=self.step) as bar:
            while self.step < c.iterations:
                total += self.train_step()
                seen += 1
                due = checkpoint is not None and checkpoint_every and self.step % checkpoint_every == 0
                if due and self.score_held_out() is not None:
                    score = f" · held-out {self.history.scores[-1]['log_psnr']:.2f} dB"
                if self.step % self.history.every == 0 or self.step == c.iterations:
                    stage = "warm-up" if self.step <= c.warmup and c.variant != "ldr" else "full"
                    self.history.rows.append({"step": self.step, "stage": stage, "loss": total / seen,
                                              "gaussians": self.model.count})
                    bar.update(self.step, info=f"loss {total / seen:.4f} · {self.model.count} Gaussians{score}")
                    total, seen = 0.0, 0
                if due:
                    self.save_checkpoint(checkpoint)
        return self.model

    def score_held_out(self) -> float | None:
        """Score the model as it stands on the dataset's held-out views, as ``dofview train-eval``
        does (GL render of the exported scene): appended to ``history.scores``; returns the mean
        log-radiance PSNR (dB), or None without held-out views or a GL renderer (said once)."""
        if not self.scoring:
            return None
        scene = self.model.to_scene("linear" if self.linear else "srgb")
        try:
            ev = evaluate(scene, self.dataset)
        except DofviewError as e:
            print(f"dofview: no held-out scores at checkpoints: {e}", file=sys.stderr)
            self.scoring = False
            return None
        ratio = ev.mean_bright_ratio  # nan when no view has a bright region: None in the JSON log
        self.history.scores.append({"step": self.step, "log_psnr": ev.mean_log_psnr,
                                    "bright_ratio": ratio if math.isfinite(ratio) else None})
        return ev.mean_log_psnr

    def save_checkpoint(self, path: Path) -> None:
        """Parameters, Adam state, step, history and scores, random states, densification
        statistics, and what made it (config, rasteriser), written whole or not at all."""
        data = {"step": self.step, "params": self.model.state(), "optimiser": self.optimiser.state_dict(),
                "history": self.history.rows, "scores": self.history.scores, "config": asdict(self.config),
                "raster": self.raster, "rng": self.rng.bit_generator.state, "torch_rng": torch.get_rng_state(),
                "grad_stats": (self.grad_sum.cpu(), self.grad_count.cpu())}
        with atomic_output(path) as tmp:
            torch.save(data, tmp)

    def load_checkpoint(self, path: Path) -> None:
        try:
            data = torch.load(path, map_location=self.device, weights_only=False)
        except (OSError, RuntimeError, EOFError) as e:
            raise DofviewError(f"{path}: cannot read checkpoint ({e})") from None
        if data.get("config", {}).get("variant") != self.config.variant:
            raise DofviewError(f"{path}: checkpoint is of variant {data.get('config', {}).get('variant')!r}, "
                               f"not {self.config.variant!r}")
        if data.get("config", {}).get("sh_degree", 0) != self.config.sh_degree:
            raise DofviewError(f"{path}: checkpoint has SH degree {data['config'].get('sh_degree', 0)}, "
                               f"not --sh-degree {self.config.sh_degree}")
        self.model = GaussianModel({k: v.to(self.device) for k, v in data["params"].items()})
        self._new_optimiser()
        try:
            self.optimiser.load_state_dict(data["optimiser"])
        except ValueError:  # parameter groups differ: written before SH bands were trained
            raise DofviewError(f"{path}: checkpoint is from an older dofview trainer; train afresh") from None
        self.step, self.history.rows = int(data["step"]), list(data["history"])
        self.history.scores = list(data.get("scores", []))
        self.rng.bit_generator.state = data["rng"]
        if "torch_rng" in data:  # (older checkpoints: the split samples after resuming differ)
            torch.set_rng_state(data["torch_rng"])
        self._reset_stats()
        if "grad_stats" in data:
            self.grad_sum, self.grad_count = (t.to(self.device) for t in data["grad_stats"])
        made = data.get("raster")
        if made is not None and made != self.raster:  # the same model: only the speed (and rounding) differ
            print(f"dofview: {path} was trained with the {made} rasteriser; going on with {self.raster}",
                  file=sys.stderr)
