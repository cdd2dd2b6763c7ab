"""The renderer backends against one another, in one run: ``python -m dofview.bench.backends``.

Whole frames during an orbit (the view turns by :data:`ORBIT_STEP_DEG` every frame, so every frame
sorts: the quad backend on the CPU plus an upload, the compute backend on the GPU), draw + display
pass, wall clock after ``glFinish``. The backends take turns frame by frame (interleaved), so that
the load of a shared machine hits both alike; the ratio compute/quad is taken from one run.
Reports per backend, scene and aperture: median, p90 and p99 frame time, FPS, the median CPU time
of the calling thread while it issues a frame (``host_ms``: time.thread_time up to the final
glFinish; a frame whose host time nears its frame time is bound by the CPU, not the GPU; on
llvmpipe it includes the rasteriser's work on that thread), the sliced mode's layers, the GPU bytes the
renderer holds afterwards (scene buffers, per-Gaussian buffers, the pair buffers at their peak) and
for the compute backend the (tile, Gaussian) pairs. Results as JSON and a PNG plot.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from dofview.camera import Camera, framing_camera
from dofview.frame import DOF_MODES, RenderSettings
from dofview.lens import Lens
from dofview.progress import Progress
from dofview.scene import GaussianScene

ORBIT_STEP_DEG = 0.5
SIZE = (1200, 675)
SAMPLES = Path(__file__).resolve().parents[2] / "samples"


def orbit(camera: Camera, pivot_distance: float, degrees: float) -> Camera:
    """``camera`` turned by ``degrees`` about its image-up axis through the point ``pivot_distance``
    ahead of it (intrinsics kept)."""
    c, axis = camera.centre, -camera.R[1]
    pivot = c + pivot_distance * camera.forward
    t = math.radians(degrees)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    q = np.eye(3) + math.sin(t) * k + (1 - math.cos(t)) * (k @ k)  # Rodrigues
    centre = pivot + q @ (c - pivot)
    r = camera.R @ q.T
    return replace(camera, R=r, T=-r @ centre)


def cases(size: tuple[int, int], sizes: tuple[int, ...], samples: bool, real: tuple[Path, ...]
          ) -> list[tuple[str, GaussianScene, Camera, float]]:
    """(label, scene, camera, focus) to measure: the bundled samples (view 0), real scenes framed by
    camera.framing_camera (focus at the scene's centre), and synthetic random scenes."""
    from dofview.bench import synth
    from dofview.io import load_scene
    from dofview.io.cameras import load_cameras_json

    out = []
    if samples:
        for name, focus in (("cards", 4.0), ("lamp", synth.LAMP_DEPTH)):
            scene = load_scene(SAMPLES / f"{name}.ply", progress=False)
            cam = load_cameras_json(SAMPLES / f"{name}_cameras.json")[0].resized(*size)
            out.append((f"{name} sample", scene, cam, focus))
    for path in real:
        scene = load_scene(path, progress=False)
        cam = framing_camera(scene, *size)
        out.append((path.name, scene, cam, float(np.linalg.norm(cam.centre - scene.means.mean(0)))))
    for n in sizes:
        out.append((f"random {n / 1e6:g}M", synth.random_scene(n, seed=6), synth.benchmark_camera(*size), 6.0))
    return out


def measure(label: str, scene: GaussianScene, camera: Camera, focus: float, apertures: tuple[float, ...],
            frames: int, backends: tuple[str, ...] = ("quad", "compute"), compute: dict | None = None,
            settings: RenderSettings = RenderSettings()) -> list[dict]:
    """Rows for one scene: every backend at every aperture, frames interleaved across backends.
    ``compute``: keyword arguments for the compute backend (tile, pix); ``settings``: the frames'
    (the default: sliced depth of field)."""
    from dofview.rendering import get_backend
    from dofview.tonemap import Tonemap

    renderers = [get_backend(name, scene, **((compute or {}) if name == "compute" else {})) for name in backends]
    ctx = renderers[0].ctx
    viewport = (0, 0, camera.width, camera.height)
    rows = []
    with Progress(f"backends: {label}", len(apertures) * (frames + 1), delay=0.0) as bar:
        for a in apertures:
            lens = Lens(focus, a)
            times: list[list[float]] = [[] for _ in renderers]
            host: list[list[float]] = [[] for _ in renderers]
            for i in range(frames + 1):  # frame 0 warms up
                cam = orbit(camera, focus, ORBIT_STEP_DEG * (i + 1))
                turn = renderers[i % 2:] + renderers[:i % 2]  # who goes first alternates
                for r in turn:
                    ctx.finish()
                    t0, c0 = time.perf_counter(), time.thread_time()
                    r.draw(cam, lens, settings)
                    r.tonemap_to(r.display_fbo, viewport, Tonemap())
                    c1 = time.thread_time()
                    ctx.finish()
                    if i:
                        times[renderers.index(r)].append((time.perf_counter() - t0) * 1e3)
                        host[renderers.index(r)].append((c1 - c0) * 1e3)
                bar.update(len(rows) // len(renderers) + i + 1, info=f"A={a:g}")
            for r, t, c in zip(renderers, times, host):
                med = float(np.median(t))
                rows.append({"scene": label, "count": scene.count, "size": [camera.width, camera.height],
                             "backend": r.name, "dof": settings.dof, "aperture": a, "median_ms": med,
                             "host_ms": float(np.median(c)), "layers": len(r.sliced_layers),
                             "p90_ms": float(np.percentile(t, 90)), "p99_ms": float(np.percentile(t, 99)),
                             "fps": 1e3 / med, "gpu_bytes": r.gpu_bytes, "bytes_per_gaussian": r.bytes_per_gaussian,
                             "pairs": getattr(r, "pairs", None), "tile": getattr(r, "tile", None),
                             "pix": getattr(r, "pix", None), "frames": frames})
    base = {row["aperture"]: row["median_ms"] for row in rows if row["backend"] == backends[0]}
    for row in rows:
        row["ratio"] = row["median_ms"] / base[row["aperture"]]
    for r in renderers:
        r.release()
    return rows


def plot(result: dict, path: Path) -> Path:
    """Bars of compute/quad frame-time ratio per scene and aperture."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dofview.io.atomic import atomic_output

    rows = [r for r in result["rows"] if r["backend"] == "compute"]
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    apertures = sorted({r["aperture"] for r in rows})
    fig, ax = plt.subplots(figsize=(6.5, 3.8))
    width = 0.8 / len(apertures)
    for j, a in enumerate(apertures):
        vals = [next((r["ratio"] for r in rows if r["scene"] == s and r["aperture"] == a), np.nan) for s in scenes]
        bars = ax.bar(np.arange(len(scenes)) + j * width, vals, width, label=f"A = {a:g}")
        ax.bar_label(bars, fmt="%.2f", fontsize=7)
    ax.axhline(1.0, color="k", lw=0.8, ls="--")
    ax.set_xticks(np.arange(len(scenes)) + width * (len(apertures) - 1) / 2, scenes, fontsize=8)
    ax.set_ylabel("frame time, compute / quad")
    ax.set_title(f"{result['gl_renderer'][:48]}, {result['size'][0]}×{result['size'][1]}, orbit (sort every frame)",
                 fontsize=9)
    ax.legend(fontsize=8)
    with atomic_output(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m dofview.bench.backends", description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="1000000", help="synthetic scene sizes (comma-separated; '' for none)")
    ap.add_argument("--apertures", default="0,100", help="apertures A (comma-separated)")
    ap.add_argument("--frames", type=int, default=3, help="timed frames per backend and aperture")
    ap.add_argument("--width", type=int, default=SIZE[0])
    ap.add_argument("--height", type=int, default=SIZE[1])
    ap.add_argument("--no-samples", action="store_true", help="skip the bundled samples")
    ap.add_argument("--real", type=Path, action="append", default=[], help="a real scene file (repeatable)")
    ap.add_argument("--compute-tile", help="TILE,PIX for the compute backend (default: its choice for this GL)")
    ap.add_argument("--dof", choices=DOF_MODES, default=RenderSettings.dof, help="depth of field mode (default %(default)s)")
    ap.add_argument("--json", type=Path, help="write the results here")
    ap.add_argument("--plot", type=Path, help="write the ratio plot (PNG) here")
    args = ap.parse_args(argv)
    from dofview.rendering.gl import headless_context

    ctx = headless_context()
    size = (args.width, args.height)
    sizes = tuple(int(s) for s in args.sizes.split(",") if s.strip())
    apertures = tuple(float(a) for a in args.apertures.split(","))
    compute = dict(zip(("tile", "pix"), map(int, args.compute_tile.split(",")))) if args.compute_tile else None
    result = {"gl_renderer": ctx.info["GL_RENDERER"], "gl_version": ctx.info["GL_VERSION"], "size": list(size),
              "orbit_step_deg": ORBIT_STEP_DEG, "command": "python -m dofview.bench.backends " + " ".join(
                  sys.argv[1:] if argv is None else argv), "rows": []}
    for label, scene, cam, focus in cases(size, sizes, not args.no_samples, tuple(args.real)):
        result["rows"] += measure(label, scene, cam, focus, apertures, args.frames, compute=compute,
                                  settings=RenderSettings(dof=args.dof))
        del scene
    text = json.dumps(result, indent=1)
    print(text)
    if args.json:
        from dofview.io.atomic import atomic_output

        with atomic_output(args.json) as tmp:
            tmp.write_text(text)
    if args.plot:
        print(f"wrote {plot(result, args.plot)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
