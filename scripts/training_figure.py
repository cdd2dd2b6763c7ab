"""Re-make docs/images/training_real_size.png: a dataset's held-out view 0, the truth beside two
trained scenes (GL render as `dofview train-eval` scores them), at the view's mid-grey key exposure
and 8 stops darker (where the lamp's radiance shows), clip and gamma 2.2.

    python scripts/training_figure.py ds_lamp lamp_no-foc.ply lamp_ldr.ply -o docs/images/training_real_size.png

(the datasets and runs of docs/TRAINING.md, "At the size of real photos").
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from dofview.io import load_scene  # noqa: E402
from dofview.io.exr import read_exr  # noqa: E402
from dofview.rendering import get_backend  # noqa: E402
from dofview.train.dataset import load_dataset  # noqa: E402
from dofview.train.evaluate import render_radiance  # noqa: E402

STOPS = (0, -8)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("dataset", type=Path)
    p.add_argument("hdr", type=Path, help="the HDR fit")
    p.add_argument("ldr", type=Path, help="the plain LDR fit")
    p.add_argument("-o", "--output", type=Path, required=True)
    args = p.parse_args()
    ds = load_dataset(args.dataset)
    channels, _ = read_exr(ds.held_out[0].hdr_path)
    truth = np.stack([channels[c] for c in "RGB"], -1)
    lit = truth.mean(-1) > 1e-4
    key = 0.18 / float(np.median(truth.mean(-1)[lit]))
    images = [truth]
    for path in (args.hdr, args.ldr):
        scene = load_scene(path, progress=False)
        renderer = get_backend("quad", scene)
        images.append(render_radiance(scene, ds, renderer)[0])
        renderer.release()
    show = lambda x, ev: (np.clip(x * key * 2.0 ** ev, 0, 1) ** (1 / 2.2) * 255 + 0.5).astype(np.uint8)  # noqa: E731
    im = Image.fromarray(np.concatenate([np.concatenate([show(i, ev) for i in images], 1) for ev in STOPS], 0))
    draw = ImageDraw.Draw(im)
    h, w = truth.shape[:2]
    for k, name in enumerate(["truth", "HDR fit (default)", "plain LDR fit"]):
        for row, ev in enumerate(STOPS):
            draw.text((k * w + 6, row * h + 4), f"{name}, {'key exposure' if ev == 0 else f'{-ev} stops darker'}",
                      fill=(255, 255, 255))
    im.save(args.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
