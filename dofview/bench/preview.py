"""The viewer's previews while the view moves (viewer/interaction.py): each depth-of-field mode at
full, half and quarter resolution, its error against the still frame (the sliced mode at full
resolution, as the viewer draws it once the view rests) and its frame time against the pinhole
frame's, on real scenes.

    python -m dofview.bench.preview SCENE... [--width 640 --height 360] [--reps 3] [--raster quad]
        [--eye X,Y,Z --target X,Y,Z --up X,Y,Z]

Per scene (viewed from its overview camera turned as the studies turn it, or from --eye/--target
for all) and case (largest blur in view 8 and 16 px, focus at the median depth), one line per
preview: PSNR (dB) of its display image, scaled up to the frame as the viewer shows it (each
pixel takes the nearest texel), against the still frame's; and its median frame time over
interleaved draws as a ratio to the pinhole frame's (one splatting pass, A = 0), in one process.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from dofview.bench.metrics import psnr
from dofview.bench.sliced_study import cases_for
from dofview.bench.study import study_views
from dofview.camera import Camera, look_at
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering import Renderer, get_backend
from dofview.tonemap import Tonemap
from dofview.tonemap.display import display

PREVIEWS = (("sliced", 1), ("splat", 1), ("sliced", 2), ("splat", 2), ("sliced", 4), ("splat", 4))
"""(dof mode, resolution divisor) as the viewer's ladder for the sliced mode (the first is the still frame)."""


def preview_view(camera: Camera, lens: Lens, dof: str, scale: int) -> tuple[Camera, Lens, RenderSettings]:
    """The camera, lens and settings of a preview at 1/``scale`` of the frame (A follows the width)."""
    w, h = max(1, camera.width // scale), max(1, camera.height // scale)
    return camera.resized(w, h), replace(lens, aperture=lens.aperture * w / camera.width), RenderSettings(dof=dof)


def shown(renderer: Renderer, width: int, height: int) -> np.ndarray:
    """(height, width, 3) the last draw's display image as the viewer shows it in a frame of that
    size: each pixel takes the texel under its centre (the display pass samples nearest)."""
    img = display(renderer.read().rgba, renderer.targets_encoded, Tonemap())
    h, w = img.shape[:2]
    rows = ((np.arange(height) + 0.5) * h / height).astype(int)
    cols = ((np.arange(width) + 0.5) * w / width).astype(int)
    return img[rows][:, cols]


def measure(renderer: Renderer, camera: Camera, lens: Lens, reps: int) -> tuple[dict[tuple[str, int], tuple[float, float]], float]:
    """{preview: (PSNR dB against the still frame, frame time / pinhole frame time)}, and the
    pinhole frame's median time (ms)."""
    views = {p: preview_view(camera, lens, *p) for p in PREVIEWS}
    views["pinhole"] = (camera, Lens(lens.focus, 0.0), RenderSettings(dof="splat"))
    times: dict[object, list[float]] = {k: [] for k in views}
    for rep in range(reps + 1):
        for k, view in views.items():
            renderer.draw(*view)  # targets of this size made and warm
            renderer.ctx.finish()
            t0 = time.perf_counter()
            renderer.draw(*view)
            renderer.ctx.finish()
            if rep:  # the first round compiles and allocates
                times[k].append(time.perf_counter() - t0)
    renderer.draw(*views[PREVIEWS[0]])
    still = shown(renderer, camera.width, camera.height)
    pinhole = float(np.median(times["pinhole"]))
    out = {}
    for p in PREVIEWS:
        renderer.draw(*views[p])
        out[p] = (psnr(shown(renderer, camera.width, camera.height), still), float(np.median(times[p])) / pinhole)
    return out, pinhole * 1e3


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m dofview.bench.preview", description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", type=Path, nargs="+")
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--raster", default="quad")
    ap.add_argument("--eye", type=lambda t: tuple(map(float, t.split(","))))
    ap.add_argument("--target", type=lambda t: tuple(map(float, t.split(","))))
    ap.add_argument("--up", type=lambda t: tuple(map(float, t.split(","))), default=(0.0, -1.0, 0.0))
    args = ap.parse_args(argv)
    from dofview.io import load_scene

    names = [f"{d}/{s}" for d, s in PREVIEWS]
    print("scene\tcase\tpinhole ms\t" + "\t".join(f"{n} dB\t{n} ×" for n in names[1:]) + f"\t{names[0]} ×")
    for path in args.scenes:
        scene = load_scene(path, progress=False)
        if args.eye is not None:
            cam = look_at(args.eye, args.target, args.width, args.height, 50.0, args.up)
        else:
            cam = study_views(scene, 1, args.width, args.height)[0]
        r = get_backend(args.raster, scene)
        try:
            for label, lens in zip(("blur8", "blur16"), cases_for(r, cam)):
                res, ms = measure(r, cam, lens, args.reps)
                cells = "\t".join(f"{res[p][0]:.1f}\t{res[p][1]:.2f}" for p in PREVIEWS[1:])
                print(f"{scene.name}\t{label}\t{ms:.0f}\t{cells}\t{res[PREVIEWS[0]][1]:.2f}", flush=True)
        finally:
            r.release()
    return 0


if __name__ == "__main__":
    sys.exit(main())
