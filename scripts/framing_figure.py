"""docs/images/framing_shared.png: the scenes of tests/data opened without cameras, before and after
issue 13 (top: the old framing, +z through the unweighted 2–98 % box with world up −y; bottom:
dofview.framing's weighted box, guessed up and 20° elevation; a scene that surrounds its centre is
seen from inside, issue 22), pinhole, focus auto; the last column is dofview.bench.synth.room_scene.

    python scripts/framing_figure.py [--scenes tests/data] [--out docs/images/framing_shared.png]

Prints, per scene, the guessed up and the coverage's α-weighted centroid offset from the image
centre (fraction of the image size) and the extent of its α > 0.5 pixels (fraction, 2–98 %).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dofview.bench.synth import room_scene
from dofview.camera import framing_camera
from dofview.framing import guess_up, overview_camera
from dofview.io import load_scene
from dofview.io.png import write_png
from dofview.lens import Lens
from dofview.rendering.focus import auto_focus
from dofview.rendering import get_backend

SCENES = ("two_planes.ply", "burger.ply", "guitar.compressed.ply", "biker.spz", "tap.spz", "room")
SIZE = (240, 180)


def placement(alpha: np.ndarray) -> tuple[float, float, float]:
    """(centroid x offset, y offset, largest extent), fractions of the image size."""
    h, w = alpha.shape
    ys, xs = np.mgrid[:h, :w] + 0.5
    a = alpha.astype(np.float64)
    off = ((a * xs).sum() / a.sum() / w - 0.5, (a * ys).sum() / a.sum() / h - 0.5)
    yy, xx = np.nonzero(alpha > 0.5)
    span = max(np.ptp(np.percentile(xx, [2, 98])) / w, np.ptp(np.percentile(yy, [2, 98])) / h) if xx.size else 0.0
    return off[0], off[1], span


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", type=Path, default=Path(__file__).resolve().parents[1] / "tests" / "data")
    p.add_argument("--out", type=Path, default=Path("docs/images/framing_shared.png"))
    args = p.parse_args()
    rows: list[list[np.ndarray]] = [[], []]
    for name in SCENES:
        scene = room_scene() if name == "room" else load_scene(args.scenes / name, progress=False)
        guess = guess_up(scene)
        renderer = get_backend("quad", scene)
        for row, cam in enumerate((framing_camera(scene, *SIZE), overview_camera(scene, *SIZE, up=guess.vector))):
            frame = renderer.render(cam, Lens(1.0, 0.0))
            focus = auto_focus(frame)
            dx, dy, span = placement(frame.alpha)
            print(f"{name:24s} {'old' if row == 0 else 'new'}: centre offset {dx:+.3f}, {dy:+.3f}; extent {span:.2f}; "
                  f"focus {'none' if focus is None else f'{focus:.3g}'}" + (f"; up {guess.label}" if row else ""))
            rows[row].append(frame.display())
        renderer.release()
    write_png(args.out, np.concatenate([np.concatenate(r, axis=1) for r in rows], axis=0))
    print(args.out)


if __name__ == "__main__":
    main()
