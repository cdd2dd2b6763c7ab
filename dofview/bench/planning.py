"""The sliced mode's planning cost per frame: the GPU plan (rendering/layer_plan.py) against the numpy
plan it replaced (the order read back, slices.plan_frame), at growing Gaussian counts.

    python -m dofview.bench.planning [--sizes 1000,1000000,10000000] [--scene FILE] [--lod N]
        [--width 1200 --height 675] [--blur 16] [--reps 5] [--raster quad,compute]

Per scene (random_scene of each size, or ``--scene`` tiled side by side up to each size), backend
and plan, the median over ``--reps`` draws' plans (after one that compiles and sorts) of:
wall ms (the plan's whole time as the frame waits for it) and host ms (time.thread_time of the
calling thread: the CPU work the frame loop does for it; on llvmpipe the GPU's kernels run on
other threads of the same CPUs and count in the wall time only). Tab-separated, one line each.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from dofview.bench.sliced_study import cases_for
from dofview.bench.synth import benchmark_camera, random_scene
from dofview.bench.study import study_views
from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering import Renderer, get_backend
from dofview.rendering.layer_plan import GpuLayerPlan
from dofview.rendering.slices import SLICE_RULE, frame_plan, plan_frame
from dofview.scene import GaussianScene

SETTINGS = RenderSettings()


def tiled(scene: GaussianScene, count: int) -> GaussianScene:
    """``scene`` repeated side by side along x (each copy shifted by the x extent of its middle 98 %)
    until it holds ``count`` Gaussians, cut there: a real capture's density at any size."""
    copies = -(-count // max(scene.count, 1))
    step = float(np.ptp(np.percentile(scene.means[:, 0], [1, 99])))
    shift = np.repeat(np.arange(copies, dtype=np.float32) * np.float32(step), scene.count)[:count]

    def tile(a: np.ndarray | None) -> np.ndarray | None:
        return None if a is None else np.concatenate([a] * copies)[:count]

    means = tile(scene.means)
    means[:, 0] += shift
    return GaussianScene(means, tile(scene.quats), tile(scene.scales), tile(scene.opacities), tile(scene.sh_dc),
                         tile(scene.sh_rest), colour_space=scene.colour_space, name=f"{scene.name}×{copies}")


def time_plans(r: Renderer, cam: Camera, lens: Lens, reps: int) -> dict[str, tuple[float, float]]:
    """{"numpy", "gpu"}: (median wall ms, median host ms) of one frame's plan, interleaved."""
    planner = GpuLayerPlan(r)
    rule = SLICE_RULE
    out: dict[str, list[tuple[float, float]]] = {"numpy": [], "gpu": []}

    def numpy_plan():
        return plan_frame(r.scene, r.front_to_back(), cam, lens, SETTINGS, rule)

    def gpu_plan():
        return frame_plan(planner.measure(cam, lens, SETTINGS, rule), cam, rule)

    try:
        for rep in range(reps + 1):
            for name, plan in (("numpy", numpy_plan), ("gpu", gpu_plan)):
                r.ctx.finish()
                t0, c0 = time.perf_counter(), time.thread_time()
                result = plan()
                t1, c1 = time.perf_counter(), time.thread_time()
                if rep:  # the first compiles
                    out[name].append((1e3 * (t1 - t0), 1e3 * (c1 - c0)))
                if name == "numpy":
                    want = result
                elif result != want:
                    raise AssertionError("the GPU plan differs from numpy's")
    finally:
        planner.release()
    return {k: (float(np.median([w for w, _ in v])), float(np.median([c for _, c in v]))) for k, v in out.items()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m dofview.bench.planning", description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="1000,1000000,10000000")
    ap.add_argument("--scene", help="a scene file to tile instead of random_scene")
    ap.add_argument("--lod", type=int, help="its level, for a streamed LOD set")
    ap.add_argument("--width", type=int, default=1200)
    ap.add_argument("--height", type=int, default=675)
    ap.add_argument("--blur", type=float, default=16.0)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--raster", default="quad,compute")
    args = ap.parse_args(argv)
    base = None
    if args.scene:
        from dofview.io import load_scene

        base = load_scene(args.scene, progress=False, lod=args.lod)
    print("scene\tgaussians\tbackend\tlayers\tnumpy wall ms\tnumpy host ms\tgpu wall ms\tgpu host ms")
    for size in (int(float(s)) for s in args.sizes.split(",")):
        scene = random_scene(size) if base is None else tiled(base, size)
        cam = (benchmark_camera(args.width, args.height) if base is None
               else study_views(base, 1, args.width, args.height)[0])
        for backend in args.raster.split(","):
            try:
                r = get_backend(backend, scene)
            except DofviewError as e:  # (the compute backend's buffers beyond this GL's limit)
                print(f"{scene.name}\t{size}\t{backend}\tnot run: {e}", flush=True)
                continue
            try:
                r.sort(cam)
                lens = cases_for(r, cam, blurs=(args.blur,))[0]
                r.draw(cam, lens, SETTINGS)
                res = time_plans(r, cam, lens, args.reps)
                layers = len(r.sliced_layers)
            finally:
                r.release()
            print(f"{scene.name}\t{size}\t{backend}\t{layers}\t{res['numpy'][0]:.1f}\t{res['numpy'][1]:.1f}\t"
                  f"{res['gpu'][0]:.1f}\t{res['gpu'][1]:.1f}", flush=True)
        del scene
    return 0


if __name__ == "__main__":
    sys.exit(main())
