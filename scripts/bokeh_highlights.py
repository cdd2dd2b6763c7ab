"""Highlight sprites of the sliced mode (issue 32) measured in one process, sprites off (the sliced
mode before them: SliceRule.sprites = 0) against on (the default):

    python scripts/bokeh_highlights.py [--backend quad|compute] [--reps 9]

1. one small bright point 2 units from the lens, focus 10, 40 px of CoC at 800 × 600 (HDR radiance
   20, σ ≈ 0.9 px and 4.3 px): the 90 → 10 % edge of its disc's radial profile and PSNR (linear,
   peak-relative) against the thin lens (1,024 pinholes), single pass and --lens-samples 8 and 32;
2. samples/lamp.ply at 480 × 360, the issue's --blur 4% --focus 1.5 and --blur 5% --focus inf,
   against the thin lens (512 pinholes): PSNR of the display image (exposure 0, clip) and of the
   linear one (the lens as the CLI resolves those options: A = 76.8 and 175);
3. frame time, sprites on over off, median of --reps draws each, interleaved (the point and both
   lamp views).
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from dofview.bench.metrics import edge_width, psnr
from dofview.bench.synth import single_gaussian
from dofview.camera import look_at
from dofview.frame import RenderSettings
from dofview.io import load_scene
from dofview.io.cameras import load_cameras_json
from dofview.lens import Lens
from dofview.rendering import get_backend
from dofview.rendering.accumulate import accumulate
from dofview.rendering.progressive import pass_settings, render_lens_samples
from dofview.rendering.slices import SLICE_RULE
from dofview.tonemap import Tonemap
from dofview.tonemap.display import display

ROOT = Path(__file__).resolve().parents[1]
OFF = replace(SLICE_RULE, sprites=0.0)
RULES = {"off": OFF, "on": None}


def light(rgba: np.ndarray) -> np.ndarray:
    """(H, W) float64 the largest channel of ``rgba`` (H, W, 4)."""
    return rgba[..., :3].max(axis=-1).astype(np.float64)


def timed(r, cam, lens, reps: int) -> dict[str, float]:
    """Median draw time ms per rule, the rules interleaved."""
    times: dict[str, list[float]] = {k: [] for k in RULES}
    for rep in range(reps + 1):
        for name, rule in RULES.items():
            r.slice_rule = rule
            t0 = time.perf_counter()
            r.draw(cam, lens, RenderSettings())
            r.ctx.finish()
            if rep:  # the first round compiles and allocates
                times[name].append(time.perf_counter() - t0)
    r.slice_rule = None
    return {k: 1e3 * float(np.median(v)) for k, v in times.items()}


def points(backend: str, reps: int) -> None:
    print("| point σ | lens | sliced off | sliced on | stage 8 off | stage 8 on | stage 32 off | stage 32 on | "
          "time on/off |")
    print("|---|---|---|---|---|---|---|---|---|")
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 800, 600, 50.0)
    lens = Lens(10.0, 2 * 40.0 / (1 / 2.0 - 1 / 10.0))
    for scale in (0.002, 0.01):
        scene = single_gaussian((0.05, 0.03, 2.0), scale, 0.95, (20.0,) * 3, colour_space="linear")
        r = get_backend(backend, scene)
        try:
            truth = light(accumulate(lambda c: r.render(c, Lens(lens.focus, 0.0), pass_settings(RenderSettings())),
                                     cam, lens, 1024).rgba)
            cells = [f"{edge_width(truth, 40.0):.1f} px"]
            for n in (1, 8, 32):
                for rule in RULES.values():
                    r.slice_rule = rule
                    img = light(render_lens_samples(r, cam, lens, RenderSettings(), n).rgba)
                    cells.append(f"{edge_width(img, 40.0):.1f} px, {psnr(img, truth, truth.max()):.1f} dB")
            t = timed(r, cam, lens, reps)
        finally:
            r.release()
        sigma = scale * cam.fx / 2.0
        print(f"| {sigma:.1f} px | " + " | ".join(cells) + f" | {t['on'] / t['off']:.2f} ({t['off']:.0f} ms off) |")


def lamp(backend: str, reps: int) -> None:
    print("\n| lamp view | display off | display on | linear off | linear on | time on/off |")
    print("|---|---|---|---|---|---|")
    scene = load_scene(ROOT / "samples" / "lamp.ply", progress=False)
    cam = load_cameras_json(ROOT / "samples" / "lamp_cameras.json")[0].resized(480, 360)
    r = get_backend(backend, scene)
    try:
        for name, lens in (("--blur 4% --focus 1.5", Lens(1.5, 76.8)), ("--blur 5% --focus inf", Lens(math.inf, 175.0))):
            truth = accumulate(lambda c: r.render(c, Lens(lens.focus, 0.0), pass_settings(RenderSettings())), cam,
                               lens, 512).rgba
            shown, peak = display(truth, False, Tonemap()), float(truth[..., :3].max())
            frames = {}
            for key, rule in RULES.items():
                r.slice_rule = rule
                frames[key] = r.render(cam, lens, RenderSettings()).rgba
            cells = [f"{psnr(display(frames[k], False, Tonemap()), shown):.2f} dB" for k in RULES]
            cells += [f"{psnr(frames[k][..., :3], truth[..., :3], peak):.2f} dB" for k in RULES]
            t = timed(r, cam, lens, reps)
            print(f"| {name} | " + " | ".join(cells) + f" | {t['on'] / t['off']:.2f} ({t['off']:.0f} ms off) |")
    finally:
        r.release()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--backend", default="quad", choices=("quad", "compute"))
    ap.add_argument("--reps", type=int, default=9)
    args = ap.parse_args()
    points(args.backend, args.reps)
    lamp(args.backend, args.reps)


if __name__ == "__main__":
    main()
