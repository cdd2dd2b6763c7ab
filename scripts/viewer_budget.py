"""The viewer's frame times while the camera moves through a streamed LOD set, per Gaussian budget,
in one process: the viewer's model headless on EGL, driven as the window drives it (each frame:
take streamed chunks, update, the display pass; ctx.finish() after it), a Markdown table for
docs/BENCHMARKS.md.

    python scripts/viewer_budget.py SET --eye=X,Y,Z --target=X,Y,Z --up=0,0,1 --budgets 3M 12M \\
        [--width 960 --height 540] [--steps 24] [--blur 8]

Per budget: the Gaussians drawn at the start, the median and slowest frame while the camera orbits
(a --step-px drag every frame: the eye moves, so the leaves' levels change) with the previews the
interaction budget chose, the Gaussians drawn and the chunk swaps at the end (for each swap taken
while moving: its upload on the UI thread, and its decode, gather, pack and sort on the worker), and
the still frame (the full sliced frame once the view rests). The lens: focus on the centre, the largest blur in view
--blur px.
"""

from __future__ import annotations

import argparse
import collections
import sys
import time

import numpy as np


def vec(text: str) -> tuple[float, float, float]:
    return tuple(float(v) for v in text.split(","))


def run(path: str, budget: int, args: argparse.Namespace) -> dict:
    from dofview.camera import look_at
    from dofview.io import load_scene
    from dofview.io.lod import open_lod
    from dofview.rendering.gl import headless_context
    from dofview.tonemap import Tonemap
    from dofview.viewer.model import ViewerModel
    from dofview.viewer.settings import ViewerSettings

    t0 = time.perf_counter()
    lod_set = open_lod(path)
    scene = load_scene(path, progress=False, budget=budget, lod_set=lod_set)
    load_s = time.perf_counter() - t0
    ctx = headless_context()
    cam = look_at(args.eye, args.target, args.width, args.height, 60.0, args.up)
    settings = ViewerSettings(colour_space=scene.colour_space, smooth_focus=False, lens_samples_max=0)
    t0 = time.perf_counter()
    model = ViewerModel(ctx, lambda: (args.width, args.height), scene, path, settings, cam, [],
                        lod_set=lod_set, budget=budget)
    model.frame_lens()
    model.settings.aperture = model.aperture_for_blur(args.blur)
    open_s = time.perf_counter() - t0
    screen = ctx.framebuffer(color_attachments=[ctx.renderbuffer((args.width, args.height), 4)])  # the window's stand-in

    def frame() -> float:
        t = time.perf_counter()
        model.update(t)
        model.renderer.tonemap_to(screen, (0, 0, args.width, args.height), Tonemap())
        ctx.finish()
        return (time.perf_counter() - t) * 1e3

    def settle() -> None:
        for _ in range(1000):
            if not model.busy:
                return
            frame()
            time.sleep(0.01)

    try:
        settle()
        start = model.scene.count
        moving, previews, swaps = [], collections.Counter(), []
        for _ in range(args.steps):
            model.controls.orbit(args.step_px, 0.0)
            before = model.stream.swaps if model.stream else 0
            moving.append(frame())
            previews[str(model.preview)] += 1
            if model.stream and model.stream.swaps > before:  # this frame took a swap in
                swaps.append((model.swap_ms, model.stream.made_s))
        time.sleep(0.2)  # rest: the next frame is the full one
        still = frame()
        settle()
        return {"budget": budget, "load_s": load_s, "open_s": open_s, "start": start, "end": model.scene.count,
                "median": float(np.median(moving)), "max": float(np.max(moving)), "still": still,
                "pinhole": model.interaction.pinhole_ms, "previews": dict(previews),
                "swaps": model.stream.swaps if model.stream else 0, "swap_frames": swaps,
                "bytes": model.renderer.gpu_bytes / max(model.scene.count, 1)}
    finally:
        model.close()
        screen.release()


def main() -> int:
    from dofview.options import gaussian_count

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("set")
    p.add_argument("--eye", type=vec, required=True)
    p.add_argument("--target", type=vec, required=True)
    p.add_argument("--up", type=vec, default=(0.0, 0.0, 1.0))
    p.add_argument("--budgets", type=gaussian_count, nargs="+", default=[3_000_000])
    p.add_argument("--width", type=int, default=960)
    p.add_argument("--height", type=int, default=540)
    p.add_argument("--steps", type=int, default=24)
    p.add_argument("--step-px", type=float, default=12.0)
    p.add_argument("--blur", type=float, default=8.0)
    args = p.parse_args()
    print("| budget | read (s) | open (s) | drawn at start | frame while moving, median / slowest (ms) | previews | "
          "drawn at end, swaps | a swap while moving: upload on the UI thread (ms) / worker (s) | still frame (ms) | "
          "pinhole frame (ms) | GPU B/Gaussian |")
    print("|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|")
    for budget in args.budgets:
        r = run(args.set, budget, args)
        previews = ", ".join(f"{k} ×{v}" for k, v in r["previews"].items())
        swaps = ", ".join(f"{ms:.0f} / {s:.1f}" for ms, s in r["swap_frames"]) or "–"
        print(f"| {budget:,} | {r['load_s']:.1f} | {r['open_s']:.1f} | {r['start']:,} | {r['median']:.0f} / "
              f"{r['max']:.0f} | {previews} | {r['end']:,}, {r['swaps']} | {swaps} | {r['still']:.0f} | {r['pinhole']:.0f} | "
              f"{r['bytes']:.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
