"""The viewer's frame times while the view moves, in one process: the viewer's model headless on
EGL, driven as the window drives it (each frame: take streamed chunks, update, the display pass;
ctx.finish() after it), a Markdown table for docs/BENCHMARKS.md.

    python scripts/viewer_budget.py SET --eye=X,Y,Z --target=X,Y,Z --up=0,0,1 --budgets 3M 12M \\
        [--width 960 --height 540] [--steps 24] [--blur 8]
    python scripts/viewer_budget.py SCENE|random:N --drag focus [--json OUT.json] ...

SCENE: a streamed LOD set, a scene file, or ``random:N`` (N random Gaussians before
bench.synth.benchmark_camera, as bench.backends measures them); without --eye/--target the view is
the one the viewer opens with (random: the benchmark camera).

Per budget (a LOD set) or scene: the Gaussians drawn at the start, the median and slowest frame,
and the median CPU time of the calling thread per frame, while the view moves with the previews the
interaction budget chose (``--drag orbit``: a --step-px drag every frame, so a LOD set's leaves
change level; ``--drag focus``: the focus slider dragged every frame, from near the nearest depth
in view to near the farthest and back, the aperture held), the Gaussians drawn and the chunk swaps
at the end (for each swap taken while moving: its upload on the UI thread, and its decode, gather,
pack and sort on the worker), and the still frame (the full sliced frame once the view rests). The
lens: focus on the centre, the largest blur in view --blur px.
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
    from pathlib import Path

    from dofview.bench import synth
    from dofview.camera import look_at
    from dofview.io import load_scene
    from dofview.io.lod import is_lod_set, open_lod
    from dofview.rendering.gl import headless_context
    from dofview.tonemap import Tonemap
    from dofview.viewer.model import ViewerModel
    from dofview.viewer.settings import ViewerSettings

    t0 = time.perf_counter()
    lod_set = cam = None
    if path.startswith("random:"):
        scene = synth.random_scene(int(float(path.partition(":")[2])), seed=6)
        cam = synth.benchmark_camera(args.width, args.height)
    else:
        lod_set = open_lod(path) if is_lod_set(path) else None
        scene = load_scene(path, progress=False, budget=budget, lod_set=lod_set)
    load_s = time.perf_counter() - t0
    ctx = headless_context()
    if args.eye is not None and args.target is not None:
        cam = look_at(args.eye, args.target, args.width, args.height, 60.0, args.up)
    settings = ViewerSettings(colour_space=scene.colour_space, smooth_focus=False, lens_samples_max=0)
    t0 = time.perf_counter()
    model = ViewerModel(ctx, lambda: (args.width, args.height), scene, Path(path), settings, cam, [],
                        lod_set=lod_set, budget=budget)
    model.frame_lens()
    model.settings.aperture = model.aperture_for_blur(args.blur)
    open_s = time.perf_counter() - t0
    screen = ctx.framebuffer(color_attachments=[ctx.renderbuffer((args.width, args.height), 4)])  # the window's stand-in

    host: list[float] = []

    def frame() -> float:
        t, c = time.perf_counter(), time.thread_time()
        model.update(t)
        model.renderer.tonemap_to(screen, (0, 0, args.width, args.height), Tonemap())
        host.append((time.thread_time() - c) * 1e3)
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
        near, far = model.depth_span
        sweep = np.geomspace(near * 1.1, far / 1.1, max(args.steps // 2, 1))
        focus = np.concatenate([sweep, sweep[::-1]])
        host.clear()
        for i in range(args.steps):
            if args.drag == "focus":
                model.settings.focus = float(focus[i % len(focus)])
            else:
                model.controls.orbit(args.step_px, 0.0)
            before = model.stream.swaps if model.stream else 0
            moving.append(frame())
            previews[str(model.preview)] += 1
            if model.stream and model.stream.swaps > before:  # this frame took a swap in
                swaps.append((model.swap_ms, model.stream.made_s))
        moving_host = float(np.median(host))
        time.sleep(0.2)  # rest: the next frame is the full one
        still = frame()
        settle()
        return {"scene": path, "drag": args.drag, "size": [args.width, args.height], "budget": budget,
                "load_s": load_s, "open_s": open_s, "start": start, "end": model.scene.count,
                "median": float(np.median(moving)), "max": float(np.max(moving)), "host": moving_host,
                "still": still, "layers": len(model.renderer.sliced_layers),
                "focus": [float(focus.min()), float(focus.max())] if args.drag == "focus" else None,
                "pinhole": model.interaction.pinhole_ms, "previews": dict(previews),
                "swaps": model.stream.swaps if model.stream else 0, "swap_frames": swaps,
                "bytes": model.renderer.gpu_bytes / max(model.scene.count, 1)}
    finally:
        model.close()
        screen.release()


def main() -> int:
    from dofview.options import gaussian_count

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("set", help="a streamed LOD set, a scene file, or random:N")
    p.add_argument("--eye", type=vec)
    p.add_argument("--target", type=vec)
    p.add_argument("--up", type=vec, default=(0.0, 0.0, 1.0))
    p.add_argument("--budgets", type=gaussian_count, nargs="+", default=[3_000_000])
    p.add_argument("--width", type=int, default=960)
    p.add_argument("--height", type=int, default=540)
    p.add_argument("--steps", type=int, default=24)
    p.add_argument("--step-px", type=float, default=12.0)
    p.add_argument("--blur", type=float, default=8.0)
    p.add_argument("--drag", choices=("orbit", "focus"), default="orbit",
                   help="what moves every frame: the camera (orbit) or the focus slider")
    p.add_argument("--json", help="also write the rows here")
    args = p.parse_args()
    if (args.eye is None) != (args.target is None):
        p.error("--eye and --target go together")
    print("| budget | read (s) | open (s) | drawn at start | frame while moving, median / slowest (ms) | "
          "host ms a frame | previews | drawn at end, swaps | a swap while moving: upload on the UI thread (ms) / "
          "worker (s) | still frame (ms) | pinhole frame (ms) | GPU B/Gaussian |")
    print("|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|")
    rows = []
    for budget in args.budgets:
        r = run(args.set, budget, args)
        rows.append(r)
        previews = ", ".join(f"{k} ×{v}" for k, v in r["previews"].items())
        swaps = ", ".join(f"{ms:.0f} / {s:.1f}" for ms, s in r["swap_frames"]) or "–"
        print(f"| {budget:,} | {r['load_s']:.1f} | {r['open_s']:.1f} | {r['start']:,} | {r['median']:.0f} / "
              f"{r['max']:.0f} | {r['host']:.1f} | {previews} | {r['end']:,}, {r['swaps']} | {swaps} | {r['still']:.0f} | "
              f"{r['pinhole']:.0f} | {r['bytes']:.0f} |", flush=True)
    if args.json:
        import json

        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
