"""docs/images/deep_card.png: a CG card put between two layers of tests/data/tap.spz in deep (the
tap's deep image and the card's, merged sample by sample and flattened, as a compositor's
DeepMerge and DeepToImage do) beside the scene rendered with the card's Gaussians.

    python scripts/deep_figure.py [--raster compute]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from dofview.api import load  # noqa: E402
from dofview.bench.deep import card, gap_depth, joined  # noqa: E402
from dofview.bench.metrics import psnr  # noqa: E402
from dofview.camera import look_at  # noqa: E402
from dofview.framing import robust_box  # noqa: E402
from dofview.lens import Lens  # noqa: E402
from dofview.rendering import get_backend  # noqa: E402
from dofview.tonemap import Tonemap, display  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--raster", default="compute")
    p.add_argument("--scene", default="two_planes.ply", help="a file of tests/data")
    args = p.parse_args()
    scene = load(ROOT / "tests" / "data" / args.scene)
    lo, hi = robust_box(scene)  # the view of tests/test_deep.py (inria_folder.ring_cameras, the second)
    centre, radius, a, tilt = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2, np.pi / 3, 0.44
    towards = np.array([np.sin(a) * np.cos(tilt), -np.sin(tilt), np.cos(a) * np.cos(tilt)])
    camera = look_at(centre - 2.5 * radius * towards, centre, 320, 240, 50.0)
    renderer = get_backend(args.raster, scene)
    flat = renderer.render(camera, Lens(1.0, 0.0)).rgba
    image = renderer.deep(camera)
    renderer.release()
    depth = gap_depth(image)
    plate = card(camera, depth, scene, box=(0.3, 0.75, 0.15, 0.6))
    renderer = get_backend(args.raster, plate)
    merged = image.merge(renderer.deep(camera)).flatten()
    renderer.release()
    renderer = get_backend(args.raster, joined(scene, plate))
    truth = renderer.render(camera, Lens(1.0, 0.0)).rgba
    renderer.release()
    encoded = scene.colour_space == "srgb"

    def shown(rgba: np.ndarray) -> np.ndarray:
        return display(rgba, encoded, Tonemap())

    panels = [(shown(flat), "the scene (flat EXR)"),
              (shown(merged), f"card merged in deep at z = {depth:.3g}, flattened"),
              (shown(truth), "the card rendered with the scene"),
              (np.clip(10 * np.abs(shown(merged) - shown(truth)), 0, 1),
               f"|difference| × 10 ({psnr(merged, truth, max(1.0, float(truth.max()))):.1f} dB linear)")]
    fig, axes = plt.subplots(1, 4, figsize=(16, 3.4))
    for ax, (img, title) in zip(axes, panels):
        ax.imshow(img)
        ax.set_title(title, fontsize=9)
        ax.axis("off")
    fig.tight_layout()
    out = ROOT / "docs" / "images" / "deep_card.png"
    fig.savefig(out, dpi=80)
    print(out)


if __name__ == "__main__":
    main()
