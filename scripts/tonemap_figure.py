"""Re-make docs/images/tonemap_operators.png: every tone-mapping operator on samples/lamp.ply and on
an HDR scene from the trainer, with the fraction of clipped and crushed covered pixels under each.

    python scripts/tonemap_figure.py                       # lamp.ply + a short training run (~3 min)
    python scripts/tonemap_figure.py --trained scene.ply   # lamp.ply + an HDR scene you trained

The trained scene: `dofview make-dataset samples/lamp.ply` (16 views, 80×60) then `dofview train`
for 800 iterations — a short run, so it is a blurrier lamp room, in the trainer's own radiance unit.
Rows: clip and the fixed curves each at its single best EV (fewest clipped + crushed pixels, ¼-stop
search from −8 to +8, ties: the brightest), the adaptive operators at 0 EV (automatic). Images are the GPU display
pass (Renderer.display_image); "clipped" = a channel at 255, "crushed" = all channels < 16.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SIZE = (240, 180)


def train_scene(folder: Path) -> Path:
    run = [sys.executable, "-m", "dofview"]
    subprocess.run([*run, "make-dataset", str(ROOT / "samples" / "lamp.ply"), "-o", str(folder / "ds"), "--views", "16",
                    "--held-out", "1", "--width", "80", "--height", "60", "--seed", "1"], check=True)
    out = folder / "trained.ply"
    subprocess.run([*run, "train", str(folder / "ds"), "-o", str(out), "--iterations", "800", "--warmup", "300",
                    "--checkpoint-every", "0"], check=True)
    return out


def best_ev(frame, operator) -> float:
    from dofview.tonemap import Tonemap, display, to_uint8
    from dofview.tonemap.stats import clipped_crushed

    def cost(ev):
        tm = Tonemap(exposure=ev, operator=operator)
        return sum(clipped_crushed(to_uint8(display(frame.rgba, frame.encoded, tm)), frame.alpha))

    return min(np.arange(8.0, -8.01, -0.25), key=cost)  # ties: the brightest


def rows_for(scene_path: Path):
    from dofview.io import load_scene
    from dofview.io.cameras import load_cameras_json
    from dofview.lens import Lens
    from dofview.rendering import get_backend
    from dofview.tonemap import OPERATORS, Tonemap
    from dofview.tonemap.stats import clipped_crushed

    r = get_backend("quad", load_scene(scene_path))
    cam = load_cameras_json(ROOT / "samples" / "lamp_cameras.json")[0].resized(*SIZE)
    frame = r.render(cam, Lens(2.5, 0.0))
    rows = []
    for name, cls in OPERATORS.items():
        e = 0.0 if cls.adaptive else best_ev(frame, cls())
        img = r.display_image(Tonemap(exposure=e, operator=cls()))
        rows.append((f"{name} ({'auto' if cls.adaptive else f'{e:+g} EV'})", img, clipped_crushed(img, frame.alpha)))
    r.release()
    return rows


def main() -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trained", type=Path, help="an HDR scene from dofview train (default: train one now)")
    p.add_argument("-o", "--output", type=Path, default=ROOT / "docs" / "images" / "tonemap_operators.png")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        trained = args.trained or train_scene(Path(tmp))
        columns = [("samples/lamp.ply", rows_for(ROOT / "samples" / "lamp.ply")), ("trained HDR scene", rows_for(trained))]
    n = len(columns[0][1])
    fig, axes = plt.subplots(n, len(columns), figsize=(3.0 * len(columns), 2.55 * n), dpi=100)
    for c, (title, rows) in enumerate(columns):
        for i, (label, img, (clipped, crushed)) in enumerate(rows):
            ax = axes[i, c]
            ax.imshow(img)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"{title}: {label}" if i == 0 else label, fontsize=8)
            ax.set_xlabel(f"clipped {100 * clipped:.1f}%  crushed {100 * crushed:.1f}%", fontsize=8)
            print(f"{title:20s} {label:24s} clipped {100 * clipped:5.1f}%  crushed {100 * crushed:5.1f}%")
    fig.tight_layout()
    args.output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.output)
    print(args.output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
