"""The GL sliced depth of field (``--dof sliced``, rendering/sliced.py) measured: frame time against
the pinhole and the per-splat mode, and PSNR against the physical thin lens next to the anchors.

    python -m dofview.bench.sliced_gl timing SCENE... [--width 640 --height 360] [--reps 5]
    python -m dofview.bench.sliced_gl quality --scenes DIR [--width 240] [--samples 64]

timing prints per scene, backend and case (A = 100; largest blur in view 16 px) the median frame
time of each mode over interleaved draws, as ratios to the pinhole's (A = 0, default settings);
quality prints per scene and case (largest blur 8 and 16 px) the PSNR of the best anchor and of
the sliced mode on each backend against the linear-light lens average (study.py's scoring).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from dofview.bench.sliced_study import ANCHOR, SCENES, cases_for
from dofview.bench.study import ANCHOR_KS, study_views
from dofview.bench.variants import errors, make_references
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering import get_backend
from dofview.rendering.sliced import MAX_FULL_RADIUS
from dofview.tonemap import Tonemap

SLICED = RenderSettings(dof="sliced")


def timing(paths: list[Path], width: int, height: int, reps: int, limits: list[float]) -> None:
    """Median frame times of pinhole, per-splat and sliced draws (each reduced-resolution limit of
    ``limits`` px, and disjoint slices at the last one), interleaved, as ratios to the pinhole's."""
    from dofview.io import load_scene

    print("scene\tbackend\tcase\tlayers\tsplat/pinhole\t" + "\t".join(f"sliced ≤{m:g}px/pinhole" for m in limits)
          + f"\tdisjoint ≤{limits[-1]:g}px/pinhole\tpinhole ms")
    for path in paths:
        scene = load_scene(path, progress=False)
        cam = study_views(scene, 1, width, height)[0]
        for backend in ("quad", "compute"):
            r = get_backend(backend, scene)
            try:
                blur16 = cases_for(r, cam, blurs=(16.0,))[0]
                r.draw(cam, blur16, SLICED)  # makes the sliced mode
                for label, lens in (("A=100", Lens(blur16.focus, 100.0)), ("blur16", blur16)):
                    modes = {"pinhole": (Lens(lens.focus, 0.0), RenderSettings(), None, True),
                             "splat": (lens, RenderSettings(), None, True), **{m: (lens, SLICED, m, True) for m in limits},
                             "disjoint": (lens, SLICED, limits[-1], False)}
                    times: dict[object, list[float]] = {m: [] for m in modes}
                    for rep in range(reps + 1):
                        for m, (ln, st, limit, share) in modes.items():
                            if limit is not None:
                                r._sliced.max_full_radius, r._sliced.share = limit, share
                            r.ctx.finish()
                            t0 = time.perf_counter()
                            r.draw(cam, ln, st)
                            r.ctx.finish()
                            if rep:  # the first round compiles and allocates
                                times[m].append(time.perf_counter() - t0)
                    med = {m: float(np.median(v)) for m, v in times.items()}
                    print(f"{scene.name}\t{backend}\t{label}\t{len(r._sliced.layers)}\t{med['splat'] / med['pinhole']:.2f}\t"
                          + "\t".join(f"{med[m] / med['pinhole']:.2f}" for m in limits)
                          + f"\t{med['disjoint'] / med['pinhole']:.2f}\t{med['pinhole'] * 1e3:.0f}",
                          flush=True)
            finally:
                r.release()


def quality(folder: Path, width: int, samples: int, only: list[str] | None, limits: list[float]) -> None:
    """PSNR of the best anchor and of the GL sliced mode (both backends, each reduced-resolution
    limit of ``limits`` px) against the thin lens."""
    from dofview.io import load_scene

    print("scene\tcase\tbest anchor dB\t" + "\t".join(f"sliced {b} ≤{m:g}px dB" for m in limits for b in ("quad", "compute")))
    for name in only or SCENES:
        scene = load_scene(folder / name, progress=False)
        cam = study_views(scene, 1, width, width * 3 // 4)[0]
        quad = get_backend("quad", scene)
        comp = get_backend("compute", scene, ctx=quad.ctx)
        try:
            for label, lens in zip(("blur8", "blur16"), cases_for(quad, cam)):
                truth = make_references(quad, cam, lens, RenderSettings(), samples, False, lambda: None).physical
                best = max(errors(quad.render(cam, lens, replace(ANCHOR, k=k)), truth, Tonemap(), False)["psnr"]
                           for k in ANCHOR_KS.values())
                got = []
                for limit in limits:
                    for r in (quad, comp):
                        r.draw(cam, lens, SLICED)  # makes the sliced mode, then its level limit is set
                        r._sliced.max_full_radius = limit
                        got.append(errors(r.render(cam, lens, SLICED), truth, Tonemap(), False)["psnr"])
                print(f"{name}\t{label}\t{best:.2f}\t" + "\t".join(f"{g:.2f}" for g in got), flush=True)
        finally:
            comp.release()
            quad.release()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m dofview.bench.sliced_gl", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="what", required=True)
    t = sub.add_parser("timing")
    t.add_argument("scenes", type=Path, nargs="+")
    t.add_argument("--width", type=int, default=640)
    t.add_argument("--height", type=int, default=360)
    t.add_argument("--reps", type=int, default=5)
    t.add_argument("--max-full-radius", type=float, action="append",
                   help="blur radius px above which slices blur at reduced resolution; repeatable (default the code's)")
    q = sub.add_parser("quality")
    q.add_argument("--scenes", type=Path, required=True)
    q.add_argument("--width", type=int, default=240)
    q.add_argument("--samples", type=int, default=64)
    q.add_argument("--only", action="append")
    q.add_argument("--max-full-radius", type=float, action="append",
                   help="blur radius px above which slices blur at reduced resolution; repeatable (default the code's)")
    args = ap.parse_args(argv)
    if args.what == "timing":
        timing(args.scenes, args.width, args.height, args.reps, args.max_full_radius or [MAX_FULL_RADIUS])
    else:
        quality(args.scenes, args.width, args.samples, args.only, args.max_full_radius or [MAX_FULL_RADIUS])
    return 0


if __name__ == "__main__":
    sys.exit(main())
