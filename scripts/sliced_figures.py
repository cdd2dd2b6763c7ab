"""The sliced depth of field's pictures for docs/images (issue 23), on llvmpipe in about a minute:

    python scripts/sliced_figures.py [--out docs/images]

- sliced_floor.png: a uniform grey floor receding from z = 0.5 to 9 (focus 3, largest blur 20 px,
  320 × 240) as the thin lens shows it (64 pinhole passes averaged in linear light), per splat
  (k = 1/4), as the depth layers composited "over" only, and as the default (the resolve closing
  the cuts); below each, its coverage stretched from 0.85 to 1 (bands show), and a plot of each
  row's coverage against the lens's.
- sliced_bokeh.png: one bright point behind focus and one in front, each 20 px of CoC, through a
  round aperture and a pentagon (rotation 0): in front of focus the pentagon is turned half a turn.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from dofview.bench.primitives import Parts  # noqa: E402
from dofview.bench.synth import receding_floor  # noqa: E402
from dofview.bench.variants import make_references  # noqa: E402
from dofview.camera import look_at  # noqa: E402
from dofview.frame import Frame, RenderSettings  # noqa: E402
from dofview.lens import Lens  # noqa: E402
from dofview.rendering import get_backend, slices  # noqa: E402
from dofview.rendering.depth_order import camera_depths  # noqa: E402
from dofview.tonemap import Tonemap  # noqa: E402
from dofview.tonemap.display import display  # noqa: E402


def over_only(renderer, cam, lens) -> Frame:
    """The depth layers composited "over" alone, without the resolve's closing of the cuts: each
    layer blended by the renderer (a sub-scene), composited by the CPU twin (slices.sliced_image,
    equal to the GL path to 90 dB) with its resolve left out."""
    renderer.sort(cam)
    order = renderer.front_to_back()
    plan = slices.plan_layers(camera_depths(renderer.scene.means[order], cam), lens, 0.01, frame=max(cam.width, cam.height))
    layers = []
    for layer in plan:
        sub = get_backend("quad", renderer.scene.subset(order[layer.first:layer.end]), ctx=renderer.ctx)
        try:
            f = sub.render(cam, Lens(lens.focus, 0.0), RenderSettings(dof="splat"))
        finally:
            sub.release()
        a = f.alpha.astype(np.float64)
        inv = np.where(f.focus_depth > 0, 1.0 / np.maximum(f.focus_depth, 1e-30), 0.0)
        layers.append((slices.to_blend_space(f.rgba, f.encoded), np.stack([f.depth * a, inv * a, 0 * a, a], -1)))
    resolve = slices.resolve
    slices.resolve = lambda over, visible: over
    try:
        colour, _ = slices.sliced_image(layers, plan, lens)
    finally:
        slices.resolve = resolve
    return Frame(rgba=slices.from_blend_space(colour, True), depth=np.zeros(colour.shape[:2], np.float32), encoded=True)


def floor(out: Path) -> None:
    scene, cam, lens = receding_floor(320, 240, 20.0)
    r = get_backend("quad", scene)
    try:
        frames = {"thin lens (64 passes)": make_references(r, cam, lens, RenderSettings(), 64, False,
                                                           lambda: None).physical,
                  "per splat (k = 1/4)": r.render(cam, lens, RenderSettings(dof="splat")),
                  "depth layers, over only": over_only(r, cam, lens),
                  "depth layers (default)": r.render(cam, lens, RenderSettings())}
    finally:
        r.release()
    fig, axes = plt.subplots(3, 4, figsize=(13, 8.2), gridspec_kw={"height_ratios": [1, 1, 1.1]})
    truth = frames["thin lens (64 passes)"]
    for i, (name, f) in enumerate(frames.items()):
        axes[0, i].imshow(display(f.rgba, f.encoded, Tonemap()))
        axes[0, i].set_title(name, fontsize=9)
        axes[1, i].imshow(np.clip((f.alpha - 0.85) / 0.15, 0, 1), cmap="gray", vmin=0, vmax=1)
        axes[1, i].set_title("coverage 0.85…1", fontsize=8)
        for ax in axes[:2, i]:
            ax.set_xticks([])
            ax.set_yticks([])
    gs = axes[2, 0].get_gridspec()
    for ax in axes[2]:
        ax.remove()
    prof = fig.add_subplot(gs[2, :])
    h, w = truth.alpha.shape
    rows, cols = np.arange(h // 2, h), slice(w // 4, 3 * w // 4)
    for name, f in frames.items():
        prof.plot(rows / h, f.alpha[rows, cols].mean(axis=1) - truth.alpha[rows, cols].mean(axis=1), label=name)
    prof.axhline(0, color="grey", lw=0.8)
    prof.set_xlabel("row (fraction of the image height, the lower half: the floor)")
    prof.set_ylabel("row coverage − lens's")
    prof.legend(fontsize=8)
    prof.grid(alpha=0.3)
    fig.suptitle("a slanted floor crossing many depth layers (focus 3, largest blur 20 px)", fontsize=10)
    fig.tight_layout()
    fig.savefig(out / "sliced_floor.png", dpi=90)
    plt.close(fig)


def bokeh(out: Path) -> None:
    parts = Parts.empty()
    front = 1.0 / (1.0 + 5.0 / 6.0)  # as far in front of focus in 1/z as z = 6 is behind it
    parts.add(np.array([[-0.9, 0.0, 6.0], [0.18 * front, 0.0, front]]), 0.002, np.array([[1.0, 1.0, 1.0]] * 2), 0.99)
    scene = parts.build("srgb", "points")
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 128, 96, 40.0)
    lens = Lens(1.0, 2 * 20.0 / (1 - 1 / 6.0))
    r = get_backend("quad", scene)
    try:
        images = [r.render(cam, lens, RenderSettings(blades=b)).alpha for b in (0, 5)]
    finally:
        r.release()
    fig, axes = plt.subplots(1, 2, figsize=(8, 3.2))
    for ax, img, name in zip(axes, images, ("round aperture", "5 blades, rotation 0")):
        for half in (slice(0, 64), slice(64, 128)):  # each point at its own brightness
            img[:, half] /= img[:, half].max()
        ax.imshow(img, cmap="gray", vmin=0, vmax=1)
        ax.set_title(f"{name}: behind focus | in front", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    fig.savefig(out / "sliced_bokeh.png", dpi=100)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=Path("docs/images"))
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    floor(args.out)
    bokeh(args.out)
    print(f"wrote {args.out / 'sliced_floor.png'} and {args.out / 'sliced_bokeh.png'}")


if __name__ == "__main__":
    main()
