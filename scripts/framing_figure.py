"""docs/images/framing_shared.png: scenes opened without cameras, before and after (each scene a
column; top: the framing before issue 13, +z through the unweighted 2–98 % box with world up −y;
under it: dofview.framing now, weighted box, guessed up and 20° elevation, a place seen from inside
at eye height, issues 22 and 31), pinhole, focus auto. The scenes: those of tests/data, the
synthetic rooms (dofview.bench.synth.room_scene, and furnished_room: a table and chairs in its
middle, 300 floaters, with and without its ceiling), the synthetic places in the open air
(synth.garden_path, synth.street), and the shared places when given.

    python scripts/framing_figure.py [--scenes tests/data] [--places ../shared/scenes]
        [--showroom showroom_l1.ply] [--out docs/images/framing_shared.png]

--places adds corridor.compressed.ply and kitchen_balcony.compressed.ply from that folder, and the
showroom from --showroom (a level decoded by ``splat-transform showroom/lod-meta.json -L 1
showroom_l1.ply``) or else the folder's showroom/lod-meta.json. Prints, per scene, the guessed up,
whether it is seen from inside and why, the coverage's α-weighted centroid offset from the image centre
(fraction of the image size), the extent of its α > 0.5 pixels (fraction, 2–98 %) and the focus.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dofview.bench.synth import furnished_room, garden_path, room_scene, street
from dofview.camera import framing_camera
from dofview.framing import Place, guess_up, judge_place, overview_camera
from dofview.io import load_scene
from dofview.io.png import write_png
from dofview.lens import Lens
from dofview.rendering import get_backend
from dofview.rendering.focus import auto_focus

ROOT = Path(__file__).resolve().parents[1]
OBJECTS = ("two_planes.ply", "burger.ply", "guitar.compressed.ply", "biker.spz", "tap.spz")
SIZE = (240, 180)
COLUMNS = 5  # scenes per band of the figure


def placement(alpha: np.ndarray) -> tuple[float, float, float]:
    """(centroid x offset, y offset, largest extent), fractions of the image size."""
    h, w = alpha.shape
    ys, xs = np.mgrid[:h, :w] + 0.5
    a = alpha.astype(np.float64)
    off = ((a * xs).sum() / a.sum() / w - 0.5, (a * ys).sum() / a.sum() / h - 0.5)
    yy, xx = np.nonzero(alpha > 0.5)
    span = max(np.ptp(np.percentile(xx, [2, 98])) / w, np.ptp(np.percentile(yy, [2, 98])) / h) if xx.size else 0.0
    return off[0], off[1], span


def scenes(args: argparse.Namespace) -> list[tuple[str, object]]:
    """(name, loader) of each scene in the figure, in column order."""
    out = [(name, lambda n=name: load_scene(args.scenes / n, progress=False)) for name in OBJECTS]
    out += [("room", room_scene), ("furnished room", lambda: furnished_room(6.0, 4.0, 2.6, doors={"-z": [(1.0, 1.9)]},
                                                                               table=True, floaters=300)),
            ("roofless room", lambda: furnished_room(6.0, 4.0, 2.6, doors={"-z": [(1.0, 1.9)]}, table=True, floaters=300,
                                                     ceiling=False)),
            ("garden path", garden_path), ("street", street)]
    if args.places:
        for name in ("corridor.compressed.ply", "kitchen_balcony.compressed.ply"):
            out.append((name, lambda n=name: load_scene(args.places / n, progress=False)))
        showroom = args.showroom or args.places / "showroom" / "lod-meta.json"
        out.append(("showroom", lambda: load_scene(showroom, progress=False)))
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", type=Path, default=ROOT / "tests" / "data")
    p.add_argument("--places", type=Path, help="the shared scenes folder (corridor, kitchen_balcony, showroom)")
    p.add_argument("--showroom", type=Path, help="the showroom as one file (a decoded level)")
    p.add_argument("--out", type=Path, default=Path("docs/images/framing_shared.png"))
    args = p.parse_args()
    columns: list[np.ndarray] = []
    for name, load in scenes(args):
        scene = load()
        guess = guess_up(scene)
        place = judge_place(scene, guess.vector)
        inside = f"inside ({place.reason})" if isinstance(place, Place) else f"outside ({place})"
        renderer = get_backend("quad", scene)
        pair = []
        for row, cam in enumerate((framing_camera(scene, *SIZE), overview_camera(scene, *SIZE, up=guess.vector))):
            frame = renderer.render(cam, Lens(1.0, 0.0))
            focus = auto_focus(frame)
            dx, dy, span = placement(frame.alpha)
            print(f"{name:30s} {'old' if row == 0 else 'new'}: centre offset {dx:+.3f}, {dy:+.3f}; extent {span:.2f}; "
                  f"focus {'none' if focus is None else f'{focus:.3g}'}"
                  + (f"; up {guess.label}; {inside}" if row else ""))
            pair.append(np.pad(frame.display()[..., :3], ((2, 2), (2, 2), (0, 0)), constant_values=255))
        renderer.release()
        columns.append(np.concatenate(pair, axis=0))
    while len(columns) % COLUMNS:
        columns.append(np.full_like(columns[0], 255))
    bands = [np.concatenate(columns[i:i + COLUMNS], axis=1) for i in range(0, len(columns), COLUMNS)]
    write_png(args.out, np.concatenate(bands, axis=0))
    print(args.out)


if __name__ == "__main__":
    main()
