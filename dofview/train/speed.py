"""Training-step speed of the trainer's rasterisers (dense, sparse, native), side by side in one run.

``python -m dofview.train.speed --gaussians 50000 --sizes 256x192,512x384`` times forward +
backward of a render (a weighted sum of colour and alpha as the loss) for each rasteriser,
interleaved (one dense step, one sparse step, one native step, …) so that other load on the
machine hits all alike, and prints steps per second and the ratios per size as a Markdown table.
The native rasteriser is left out, with a notice, where its C file cannot be built.

The scene is random (seeded): Gaussians in the camera's frustum at depths 2…8, anisotropic,
about 0.5–3 px standard deviation at 512 px wide, opacities 0.05–1, through a lens of aperture
strength ``--aperture`` focused at depth 4 (so splats behind and in front are CoC-enlarged).
"""

from __future__ import annotations

import argparse
import functools
import statistics
import sys
import time
from typing import Callable

import numpy as np
import torch

from dofview.camera import Camera, look_at
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.train.optimise import TRAIN_RENDER
from dofview.train.native import NativeUnavailable, default_threads, library, rasterise_native
from dofview.train.rasterisers import RASTERISERS


def frustum_scene(count: int, camera: Camera, seed: int = 0) -> list[torch.Tensor]:
    """(means, quats, log-scales, opacity logits, colours) leaf tensors of ``count`` random
    Gaussians seen by ``camera`` (float32; see the module docstring)."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(2.0, 8.0, count)
    px, py = rng.uniform(0, camera.width, count), rng.uniform(0, camera.height, count)
    means = camera.centre + z[:, None] * np.stack([camera.pixel_ray(x, y) for x, y in zip(px, py)])
    sigma_px = np.exp(rng.uniform(np.log(0.5), np.log(3.0), (count, 3))) * camera.width / 512
    scales = sigma_px * z[:, None] / camera.fx
    scales[np.arange(count), rng.integers(0, 3, count)] *= 0.1  # flat, as trained splats often are
    opacity = rng.uniform(0.05, 0.99, count)
    arrays = (means, rng.normal(size=(count, 4)), np.log(scales), np.log(opacity / (1 - opacity)),
              rng.uniform(0.05, 2.0, (count, 3)))
    return [torch.tensor(a, dtype=torch.float32, requires_grad=True) for a in arrays]


def step(raster, params: list[torch.Tensor], camera: Camera, lens: Lens, settings: RenderSettings,
         weights: tuple[torch.Tensor, torch.Tensor]) -> float:
    """Seconds for one forward + backward of ``raster``."""
    for p in params:
        p.grad = None
    t0 = time.perf_counter()
    means, quats, log_scales, logits, colours = params
    r = raster(means, quats, torch.exp(log_scales), torch.sigmoid(logits), colours, camera, lens, settings)
    ((r.rgb * weights[0]).sum() + (r.alpha * weights[1]).sum()).backward()
    return time.perf_counter() - t0


def measure(count: int, width: int, height: int, repeats: int, aperture: float,
            rasterisers: dict[str, Callable]) -> dict[str, float]:
    """Median steps per second of each of ``rasterisers`` (name → function), interleaved (one
    warm-up step each, not timed)."""
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 5.0), width, height, 60.0)
    params = frustum_scene(count, cam)
    lens = Lens(focus=4.0, aperture=aperture * width / 512)
    g = torch.Generator().manual_seed(1)
    weights = (torch.rand(height, width, 3, generator=g), torch.rand(height, width, generator=g))
    times: dict[str, list[float]] = {n: [] for n in rasterisers}
    for rep in range(repeats + 1):
        for n, raster in rasterisers.items():
            t = step(raster, params, cam, lens, TRAIN_RENDER, weights)
            if rep:
                times[n].append(t)
    return {n: 1.0 / statistics.median(ts) for n, ts in times.items()}


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise DofviewError(f"--sizes: each size is WIDTHxHEIGHT, got {text!r}") from None
    if w < 16 or h < 16:
        raise DofviewError(f"--sizes: {text} is smaller than one 16×16 tile")
    return w, h


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m dofview.train.speed", description=__doc__.split("\n\n")[0])
    p.add_argument("--gaussians", type=int, default=50000)
    p.add_argument("--sizes", default="256x192,512x384")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--aperture", type=float, default=20.0, help="aperture strength A at 512 px wide (default 20)")
    p.add_argument("--threads", type=int, default=1, help="torch threads (the trainer uses 1 on CPU)")
    p.add_argument("--native-threads", type=int, default=default_threads(),
                   help="the native rasteriser's compositing threads (default: the cores this process may use, "
                        "as the trainer)")
    args = p.parse_args(argv)
    try:
        sizes = [_size(s) for s in args.sizes.split(",")]
    except DofviewError as e:
        print(f"dofview: error: {e}", file=sys.stderr)
        return 2
    torch.set_num_threads(args.threads)
    rasterisers = dict(RASTERISERS)
    try:
        library(torch.float32)
        rasterisers["native"] = functools.partial(rasterise_native, threads=args.native_threads)
    except NativeUnavailable as e:
        print(f"dofview: {e}; timing dense and sparse only", file=sys.stderr)
        del rasterisers["native"]
    print(f"torch {torch.__version__}, {args.threads} torch thread(s), {args.native_threads} native thread(s), "
          f"aperture {args.aperture:g} at 512 px")
    names = list(rasterisers)
    ratios = [(a, b) for a, b in (("sparse", "dense"), ("native", "dense"), ("native", "sparse")) if a in names]
    print("| size | Gaussians | " + " | ".join(f"{n} steps/s" for n in names) + " | "
          + " | ".join(f"{a} / {b}" for a, b in ratios) + " |")
    print("|---" * (2 + len(names) + len(ratios)) + "|")
    for w, h in sizes:
        r = measure(args.gaussians, w, h, args.repeats, args.aperture, rasterisers)
        print(f"| {w}×{h} | {args.gaussians} | " + " | ".join(f"{r[n]:.3f}" for n in names) + " | "
              + " | ".join(f"{r[a] / r[b]:.1f}×" for a, b in ratios) + " |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
