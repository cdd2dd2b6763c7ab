"""Progressive thin lens against the physical truth: stages of sub-aperture passes against the
pinhole average they replaced (issue 23).

For each real scene (one study view, study.py) and place view (dofview/bench/places) and each
largest blur in view (8 and 16 px, sliced_study.scene_cases): the PSNR of the display image against the physical truth (the
linear-light average of ``--samples`` pinhole images, variants.make_references) of
- the anchors' single pass (per-splat, energy normalisation, τ = 1/255, k = 1/9, 1/4, 1) — the
  best of them is the figure to beat — and the default single pass (sliced),
- the pinhole-average refinement (N pinhole passes at the R2 points of disk_sequence, τ = 0),
- the stage refinement of the default (N lens cells, each blurred by its own shape:
  ``dofview render --lens-samples N``) and of the per-splat mode (N passes of the sub-aperture
  A/√N at progressive.stage_points).

    python -m dofview.bench.refinement --scenes DIR [--width 240] [--samples 64] [--only NAME]
        [--stages 64] [--lod 1] [--plot docs/images/refinement.png] [--ghosts docs/images/refinement_ghosts.png]

prints one tab-separated line per scene, case, method and N: PSNR, and PSNR over the best anchor.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from dofview.bench.sliced_study import ANCHOR, SCENES, place_view_names, scene_cases
from dofview.bench.study import ANCHOR_KS
from dofview.bench.variants import errors, make_references
from dofview.frame import Frame, RenderSettings
from dofview.lens import Lens
from dofview.rendering import Renderer, get_backend
from dofview.rendering.accumulate import accumulate
from dofview.rendering.progressive import pass_settings, render_lens_samples
from dofview.tonemap import Tonemap
from dofview.tonemap.display import display

COUNTS = (2, 4, 8, 16)
GHOST_N = 4


PLASTIC = 1.324717957244746  # the plastic number: the 2D golden ratio of the R2 sequence


def disk_sequence(n: int) -> np.ndarray:
    """(n, 2) float64 points of the unit disk: the first n of the R2 low-discrepancy sequence
    (Roberts 2018) mapped area-preservingly (r = √u₁, θ = 2π·u₂); a prefix of one infinite sequence
    for every n. The lens points of the pinhole-average refinement that
    rendering/progressive.py's stages replaced, kept here as this benchmark's comparison."""
    i = np.arange(1, n + 1, dtype=np.float64)[:, None]
    u = np.mod(0.5 + i * np.array([1.0 / PLASTIC, 1.0 / PLASTIC ** 2]), 1.0)
    r, th = np.sqrt(u[:, 0]), 2.0 * math.pi * u[:, 1]
    return np.stack([r * np.cos(th), r * np.sin(th)], axis=1)


def pinhole_average(renderer: Renderer, camera, lens: Lens, n: int) -> Frame:
    """The refinement this module's stages replaced: n pinhole passes at the R2 lens points."""
    pin, st = Lens(lens.focus, 0.0), pass_settings(RenderSettings())
    return accumulate(lambda c: renderer.render(c, pin, st), camera, lens, n, points=disk_sequence(n))


def study_case(renderer: Renderer, camera, lens: Lens, samples: int, tm: Tonemap = Tonemap(),
               counts: tuple[int, ...] = COUNTS, stages_only: tuple[int, ...] = ()) -> tuple[list[tuple[str, int, float]], dict[str, Frame]]:
    """(method, N, PSNR) rows of one case, and the frames of the ghost figure (truth, best anchor,
    both refinements at :data:`GHOST_N`); ``stages_only``: more stage counts of the default alone
    (e.g. 64, where the pinhole average and the per-splat stages would cost as much again)."""
    truth = make_references(renderer, camera, lens, RenderSettings(), samples, False, lambda: None).physical
    rows, frames = [], {"truth": truth}
    best = None
    for name, k in ANCHOR_KS.items():
        f = renderer.render(camera, lens, replace(ANCHOR, k=k))
        p = errors(f, truth, tm, False)["psnr"]
        rows.append((name, 1, p))
        if best is None or p > best[1]:
            best, frames["best anchor"] = (name, p), f
    rows.append(("pinhole", 1, errors(renderer.render(camera, replace(lens, aperture=0.0), RenderSettings()), truth, tm,
                                      False)["psnr"]))  # what "never below the pinhole" compares with
    rows.append(("sliced", 1, errors(renderer.render(camera, lens, RenderSettings()), truth, tm, False)["psnr"]))
    for n in stages_only:
        rows.append(("stages", n, errors(render_lens_samples(renderer, camera, lens, RenderSettings(), n), truth, tm,
                                         False)["psnr"]))
    for n in counts:
        f_old = pinhole_average(renderer, camera, lens, n)
        f_new = render_lens_samples(renderer, camera, lens, RenderSettings(), n)
        f_splat = render_lens_samples(renderer, camera, lens, RenderSettings(dof="splat"), n)
        rows.append(("pinhole average", n, errors(f_old, truth, tm, False)["psnr"]))
        rows.append(("stages", n, errors(f_new, truth, tm, False)["psnr"]))
        rows.append(("per-splat stages", n, errors(f_splat, truth, tm, False)["psnr"]))
        if n == GHOST_N:
            frames["pinhole average"], frames["stages"] = f_old, f_new
    return rows, frames


def plot(path: Path, table: dict[tuple[str, str], list[tuple[str, int, float]]], title: str) -> None:
    """PSNR against N per scene: both refinements for each blur, the best anchor as a level."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(s for s, _ in table))
    cols = min(len(scenes), 6)
    rows_of = -(-len(scenes) // cols)
    fig, axes = plt.subplots(rows_of, cols, figsize=(3.2 * cols, 3.0 * rows_of + 0.6), squeeze=False)
    for ax in axes.flat[len(scenes):]:
        ax.set_visible(False)
    counts = sorted({n for rows in table.values() for _, n, _ in rows} | {1})
    for ax, scene in zip(axes.flat, scenes):
        for (s, case), rows in table.items():
            if s != scene:
                continue
            ls = "-" if case == "blur16" else "--"
            best = max(p for m, _, p in rows if m in ANCHOR_KS)
            ax.axhline(best, color="grey", ls=ls, lw=1, label=f"best per-splat single pass, {case}")
            for m, _, p in rows:
                if m == "pinhole":
                    ax.axhline(p, color="black", ls=":" if case == "blur16" else (0, (1, 3)), lw=1, label=f"pinhole, {case}")
            for method, colour in (("pinhole average", "tab:red"), ("per-splat stages", "tab:green"),
                                   ("stages", "tab:blue")):
                pts = sorted((n, p) for m, n, p in rows if m == method or (method == "stages" and m == "sliced"))
                ax.plot([n for n, _ in pts], [p for _, p in pts], ls, marker="o", ms=3, color=colour,
                        label=f"{method}, {case}")
        ax.set_xscale("log", base=2)
        ax.set_xticks(counts, [str(n) for n in counts])
        ax.set_xlabel("N (passes)")
        ax.set_title(scene, fontsize=9)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("PSNR against the thin lens (dB)")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=6, fontsize=7, frameon=False)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout(rect=(0, 0.08 / axes.shape[0], 1, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def ghost_figure(path: Path, frames: dict[str, Frame], rows: list[tuple[str, int, float]], title: str,
                 tm: Tonemap = Tonemap(), zoom: int = 2) -> None:
    """Truth | best anchor | pinhole average | stages (N = GHOST_N), each labelled with its PSNR."""
    from PIL import Image, ImageDraw

    psnr = {m: p for m, n, p in rows if n == GHOST_N}
    best = max((p, m) for m, n, p in rows if m in ANCHOR_KS)
    labels = {"truth": "thin lens (truth)", "best anchor": f"per-splat {best[1]}: {best[0]:.2f} dB",
              "pinhole average": f"pinhole average N={GHOST_N}: {psnr['pinhole average']:.2f} dB",
              "stages": f"stages N={GHOST_N}: {psnr['stages']:.2f} dB"}
    panels = []
    for key, label in labels.items():
        f = frames[key]
        img = Image.fromarray((np.clip(display(f.rgba, f.encoded, tm), 0, 1) * 255 + 0.5).astype(np.uint8))
        img = img.resize((img.width * zoom, img.height * zoom), Image.NEAREST)
        ImageDraw.Draw(img).text((4, 4), label, fill=(255, 255, 255))
        panels.append(img)
    w, h = panels[0].size
    sheet = Image.new("RGB", (2 * w, 2 * h + 16), (0, 0, 0))
    for i, p in enumerate(panels):
        sheet.paste(p, ((i % 2) * w, 16 + (i // 2) * h))
    ImageDraw.Draw(sheet).text((4, 2), title, fill=(255, 255, 255))
    path.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(path)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m dofview.bench.refinement", description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", type=Path, required=True, help="folder of the five real scenes")
    ap.add_argument("--width", type=int, default=240)
    ap.add_argument("--samples", type=int, default=64, help="pinhole passes of the truth")
    ap.add_argument("--only", action="append", help="scene file name or place view (corridor_1, …); repeatable")
    ap.add_argument("--lod", type=int, default=1, help="the showroom's level (0: 1.5M Gaussians, 1: 747k)")
    ap.add_argument("--stages", type=int, action="append", default=[],
                    help="a stage of the default alone beside 2, 4, 8, 16 (e.g. 64); repeatable")
    ap.add_argument("--raster", default="quad")
    ap.add_argument("--plot", type=Path, help="PNG of PSNR against N per scene")
    ap.add_argument("--ghosts", type=Path, help=f"PNG of both refinements at N = {GHOST_N} (first scene, 16 px)")
    args = ap.parse_args(argv)
    names = args.only or [*SCENES, *place_view_names()]
    h = args.width * 3 // 4
    table: dict[tuple[str, str], list[tuple[str, int, float]]] = {}
    for name in names:
        scene, cam, lenses = scene_cases(name, args.scenes, args.width, args.lod)
        renderer = get_backend(args.raster, scene)
        t0 = time.perf_counter()
        try:
            for label, lens in lenses(renderer):
                rows, frames = study_case(renderer, cam, lens, args.samples, stages_only=tuple(args.stages))
                table[(name, label)] = rows
                best = max(p for m, _, p in rows if m in ANCHOR_KS)
                for method, n, p in rows:
                    print(f"{name}\t{label}\t{method}\t{n}\t{p:.2f}\t{p - best:+.2f}", flush=True)
                if args.ghosts and name == names[0] and label == "blur16":
                    ghost_figure(args.ghosts, frames, rows, f"{name}, {label}, {args.width}x{h}, N = {GHOST_N}")
        finally:
            renderer.release()
        print(f"# {name}: {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
    if args.plot:
        plot(args.plot, table, f"progressive thin lens against the physical truth ({args.samples} pinhole passes), "
                               f"{args.width}x{h}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
