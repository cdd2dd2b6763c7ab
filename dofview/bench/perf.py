"""Performance at scale, measured in one run: ``python -m dofview.bench.perf [--quick] [--only load,sort,…]``.

Sub-measurements (each a function returning a JSON-able dict):

- ``load``: 3DGS ``.ply`` files of SH degree 3 written to a temp folder are loaded (read + activate,
  pack, upload) in a fresh subprocess each, which reports the time of each step and its peak host
  memory: the growth of VmHWM over the process's resident size before loading (file pages mapped by
  the reader count too) and the peak of Python/numpy allocations (tracemalloc), both against the
  file size.
- ``sort``: the depth sort (dofview.sort.front_to_back) against numpy's stable argsort of the same
  float32 depths, same run, for several scene sizes, in wall and process CPU time; plus its steps.
- ``ui``: the longest stall of a UI-like polling loop while the viewer's sort thread sorts 1M
  Gaussians, against the sort time.
- ``memory``: GPU bytes per Gaussian reported by the renderer, packed and float32, SH degree 0 and 3.
- ``culling``: what vertex-stage culling (culled Gaussians become degenerate quads) costs against an
  ideally compacted draw of only the visible Gaussians: frame time of a visible set alone, and of the
  same set plus as many Gaussians outside the frustum, or behind the camera. The difference bounds
  what a compute pre-pass that compacts the visible set could save.
- ``fragments``: fragments rasterised per frame at A = 0 and A = 100 by the renderer's tight quads
  (τ = 0 and τ default) and by 3σ squares (τ = 0, the reference rasteriser's bound), counted from the CPU
  reference's projected footprints (reference.project), with the GL renderer's own counts of
  Gaussians drawn and of fragments that passed the α cut (an occlusion query) beside them.
- ``bottleneck``: frame time at A = 0 as the image shrinks, SH degree 3 and 0: fragment-bound
  frames shrink with the pixel count, vertex-bound ones do not.
- ``frames``: frame time (wall clock, GPU work finished) of random scenes at 1200×675 with depth of
  field, A = 0, 50, 100, τ default. Absolute times mean something on a real GPU only.

Results go to a JSON file and PNG plots (docs/images/perf_*.png by default).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Callable

import numpy as np

from dofview.frame import RenderSettings
from dofview.progress import Progress

MEASUREMENTS = ("load", "sort", "ui", "memory", "culling", "fragments", "frames", "bottleneck")
PER_SPLAT = RenderSettings(dof="splat")
"""The frames measured here: the per-splat pass (its fragments are the quads counted; the figures in
docs/BENCHMARKS.md "Performance at scale" are of it). The sliced mode's frames: bench.backends --dof."""
FRAME_SIZE = (1200, 675)
FOCUS = 6.0  # scene units: mid-depth of synth.random_scene's 2…20 range
APERTURES = (0.0, 50.0, 100.0)


def _median_ms(fn: Callable[[], object], repeat: int, clock: Callable[[], float] = time.perf_counter) -> float:
    """Median over ``repeat`` calls of ``fn``, in ms of ``clock`` (wall, or process CPU time, which
    a machine shared with other work inflates far less)."""
    times = []
    for _ in range(repeat):
        t0 = clock()
        fn()
        times.append(clock() - t0)
    return float(np.median(times) * 1e3)


# ---- load ------------------------------------------------------------------------------------
def _status_kib(field: str) -> int:
    """A ``/proc/self/status`` field in KiB (VmHWM, VmRSS); ru_maxrss where /proc is missing."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1])
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def _reset_peak() -> bool:
    """Reset VmHWM to the current resident size (Linux ≥ 4.0); False where that is impossible."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
        return True
    except OSError:
        return False


def load_child(path: str, raster: str = "quad") -> dict:
    """Load ``path`` as the viewer does (read, pack, upload) and report times and peak memory.

    Run in a fresh process (``--load-child``) so that the peak belongs to this load alone. The GL
    context and a tiny renderer of the same SH degree exist before the baseline, so their fixed cost
    is not counted against the file.
    """
    import tracemalloc

    from dofview.io.ply import read_ply
    from dofview.rendering.gl import headless_context
    from dofview.rendering import get_backend
    from dofview.rendering.packing import gpu_arrays

    ctx = headless_context()
    probe = read_ply(path)  # warms imports; released before the baseline
    get_backend(raster, probe.subset(np.arange(min(probe.count, 16))), ctx).release()
    del probe
    resettable = _reset_peak()
    base_kib = _status_kib("VmRSS")
    tracemalloc.start()
    t0 = time.perf_counter()
    scene = read_ply(path)
    t1 = time.perf_counter()
    renderer = get_backend(raster, scene, ctx)
    ctx.finish()
    t2 = time.perf_counter()
    _, traced_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    peak_kib = _status_kib("VmHWM")
    t3 = time.perf_counter()
    gpu_arrays(scene)  # packing alone (part of renderer_s), timed after the peak was read
    pack_s = time.perf_counter() - t3
    return {
        "count": scene.count, "file_bytes": os.path.getsize(path),
        "read_activate_s": t1 - t0, "renderer_s": t2 - t1, "pack_s": pack_s, "total_s": t2 - t0,
        "peak_rss_growth_bytes": (peak_kib - base_kib) * 1024 if resettable else None,
        "traced_peak_bytes": traced_peak, "gpu_bytes_per_gaussian": renderer.bytes_per_gaussian,
    }


def measure_load_file(path: str | Path, raster: str = "quad") -> dict:
    """Run :func:`load_child` for ``path`` in a fresh Python process and return its report."""
    out = subprocess.run([sys.executable, "-m", "dofview.bench.perf", "--load-child", str(path), "--raster", raster],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def measure_load(sizes: tuple[int, ...], folder: Path, raster: str = "quad") -> dict:
    from dofview.bench.synth import random_scene
    from dofview.io.ply import write_ply

    rows = []
    with Progress("perf: load", len(sizes), delay=0.0) as bar:
        for i, n in enumerate(sizes):
            path = folder / f"random_{n}_deg3.ply"
            write_ply(random_scene(n, degree=3, seed=1), path)
            rows.append(measure_load_file(path, raster))
            path.unlink()
            bar.update(i + 1, info=f"{n} Gaussians")
    return {"rows": rows}


# ---- sort ------------------------------------------------------------------------------------
def measure_sort(sizes: tuple[int, ...], repeat: int) -> dict:
    from dofview.bench.synth import benchmark_camera, random_scene
    from dofview.rendering.depth_order import (
        argsort_keys,
        camera_depths,
        depth_keys,
        front_to_back,
    )

    cam = benchmark_camera()
    rows = []
    with Progress("perf: sort", len(sizes), delay=0.0) as bar:
        for i, n in enumerate(sizes):
            means = random_scene(n, seed=2).means
            z = camera_depths(means, cam)
            keys = depth_keys(z)
            row = {
                "count": n,
                "front_to_back_ms": _median_ms(lambda: front_to_back(means, cam), repeat),
                "argsort_stable_ms": _median_ms(lambda: np.argsort(z, kind="stable"), repeat),
                "front_to_back_cpu_ms": _median_ms(lambda: front_to_back(means, cam), repeat, time.process_time),
                "argsort_stable_cpu_ms": _median_ms(lambda: np.argsort(z, kind="stable"), repeat, time.process_time),
                "depths_ms": _median_ms(lambda: camera_depths(means, cam), repeat),
                "keys_ms": _median_ms(lambda: depth_keys(z), repeat),
                "radix_ms": _median_ms(lambda: argsort_keys(keys), repeat),
            }
            row["ratio_to_argsort"] = row["front_to_back_ms"] / row["argsort_stable_ms"]
            rows.append(row)
            bar.update(i + 1, info=f"{n}")
    return {"rows": rows, "repeat": repeat}


def measure_ui_stall(n: int, repeat: int) -> dict:
    """The quad backend's sort thread (dofview.rendering.sort_thread, as the viewer runs it) sorting
    ``n`` Gaussians for a new view while this thread plays the UI, polling for the result every millisecond as a frame loop would: the
    longest gap between its polls against the sort time. A sort that held the interpreter lock
    would stall the UI for the whole sort (gap ≈ sort time)."""
    from dofview.bench.synth import random_scene
    from dofview.camera import look_at
    from dofview.rendering.sort_thread import SortThread

    means = random_scene(n, seed=7).means
    worker = SortThread()
    rows = []
    try:
        for i in range(repeat):
            cam = look_at((0.1 * i, 0.0, 0.0), (0.0, 0.0, 10.0), 1280, 720, 60.0)
            worker.request(means, cam)
            last = start = time.perf_counter()
            longest = 0.0
            while (res := worker.result()) is None:
                time.sleep(0.001)
                now = time.perf_counter()
                longest, last = max(longest, now - last), now
            rows.append({"sort_ms": res.ms, "longest_ui_gap_ms": longest * 1e3,
                         "request_to_result_ms": (time.perf_counter() - start) * 1e3})
    finally:
        worker.close()
    return {"count": n, "rows": rows}


# ---- GPU memory --------------------------------------------------------------------------------
def measure_memory(n: int, raster: str = "quad") -> dict:
    from dofview.bench.synth import random_scene
    from dofview.rendering import get_backend

    rows = []
    for degree in (0, 3):
        scene = random_scene(n, degree=degree, seed=3)
        for packed in (True, False):
            r = get_backend(raster, scene, packed=packed)
            rows.append({"degree": degree, "packed": packed, "bytes_per_gaussian": r.bytes_per_gaussian})
            r.release()
    return {"count": n, "raster": raster, "rows": rows, "note": "includes the backend's own per-Gaussian buffers "
            "(the quad backend's: the 4 B/Gaussian draw order)"}


# ---- drawing ---------------------------------------------------------------------------------
def time_frames(renderer, camera, lens, settings, frames: int) -> dict:
    """Mean wall time per frame of draw + display pass, view fixed, GPU work finished.

    The GL timer query is not used: on NVIDIA's driver moderngl's query objects returned one stale
    value for later queries. ``finish()`` after ``frames`` frames makes the wall time GPU time
    plus the (small) per-frame Python overhead.
    """
    from dofview.tonemap import Tonemap

    ctx = renderer.ctx
    tm = Tonemap()
    viewport = (0, 0, camera.width, camera.height)
    renderer.draw(camera, lens, settings)  # sorts once, warms the pipeline
    renderer.tonemap_to(renderer.display_fbo, viewport, tm)
    ctx.finish()
    t0 = time.perf_counter()
    for _ in range(frames):
        renderer.draw(camera, lens, settings)
        renderer.tonemap_to(renderer.display_fbo, viewport, tm)
    ctx.finish()
    return {"wall_ms": (time.perf_counter() - t0) / frames * 1e3}


def _with_hidden(scene, where: str):
    """``scene`` followed by a copy of it that the camera of synth.random_scene cannot see."""
    from dofview.scene import GaussianScene

    moved = scene.means.copy()
    if where == "frustum":  # beside the view: projected, then culled by the screen-extent test
        moved[:, 0] += 3.0 * moved[:, 2]
    else:  # behind the camera: culled by the near-plane test first thing
        moved[:, 2] *= -1.0
    twice = lambda a: None if a is None else np.concatenate([a, a])
    return GaussianScene(means=np.concatenate([scene.means, moved]), quats=twice(scene.quats),
                         scales=twice(scene.scales), opacities=twice(scene.opacities), sh_dc=twice(scene.sh_dc),
                         sh_rest=twice(scene.sh_rest), name=f"{scene.name} + hidden")


def measure_culling(n: int, size: tuple[int, int], frames: int, raster: str = "quad") -> dict:
    from dofview.bench.synth import benchmark_camera, random_scene
    from dofview.lens import Lens
    from dofview.rendering import get_backend

    cam = benchmark_camera(*size)
    visible = random_scene(n, degree=3, seed=4)
    rows = []
    variants = (("visible only (ideal compaction)", visible), ("+ same count beside the frustum",
                _with_hidden(visible, "frustum")), ("+ same count behind the camera", _with_hidden(visible, "behind")))
    with Progress("perf: culling", len(variants) * 2, delay=0.0) as bar:
        for name, scene in variants:
            r = get_backend(raster, scene)
            for aperture in (0.0, 100.0):
                row = {"variant": name, "count": scene.count, "aperture": aperture}
                row.update(time_frames(r, cam, Lens(FOCUS, aperture), PER_SPLAT, frames))
                r.draw(cam, Lens(FOCUS, aperture), PER_SPLAT, count=True)
                row["drawn"] = r.stats.drawn
                rows.append(row)
                bar.update(len(rows))
            r.release()
    return {"size": list(size), "raster": raster, "rows": rows}


def quad_fragments(pr: dict, width: int, height: int, shape: str) -> np.ndarray:
    """(M,) estimated pixels rasterised per Gaussian, from reference.project output ``pr``.

    ``shape`` "tight": the renderer's quad, the rectangle of half sides r·√λ + ½ px along the
    eigen-axes of the blurred covariance, r² = pr["r2"] (rendering/glsl/quads.vert). "3sigma": an
    axis-aligned square of half side 3·√λ₁ (the reference 3DGS rasteriser's bound). Areas are
    clipped to the image: exactly for the square, for the rotated rectangle by the fraction of its
    axis-aligned box that lies inside.
    """
    sxx, sxy, syy = pr["cov"].T
    half_diff = 0.5 * (sxx - syy)
    root = np.sqrt(half_diff ** 2 + sxy ** 2)
    l1 = 0.5 * (sxx + syy) + root
    l2 = np.maximum(sxx * syy - sxy * sxy, 0.0) / l1
    if shape == "tight":
        r = np.sqrt(pr["r2"])
        hx, hy = r * np.sqrt(l1) + 0.5, r * np.sqrt(l2) + 0.5
        theta = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)
        c, s = np.abs(np.cos(theta)), np.abs(np.sin(theta))
        ex, ey = c * hx + s * hy, s * hx + c * hy
        area = 4.0 * hx * hy
    else:
        ex = ey = 3.0 * np.sqrt(l1)
        area = 4.0 * ex * ey
    x, y = pr["mean2d"].T
    inside_x = np.clip(np.minimum(x + ex, width) - np.maximum(x - ex, 0.0), 0.0, None)
    inside_y = np.clip(np.minimum(y + ey, height) - np.maximum(y - ey, 0.0), 0.0, None)
    return area * inside_x * inside_y / np.maximum(4.0 * ex * ey, 1e-30)


def measure_fragments(n: int, size: tuple[int, int]) -> dict:
    from dofview.bench.synth import benchmark_camera, random_scene
    from dofview.lens import Lens
    from dofview.rendering import get_backend
    from dofview.rendering.footprint import project

    cam = benchmark_camera(*size)
    scene = random_scene(n, degree=0, seed=5)
    renderer = get_backend("quad", scene)  # the fragments of its quads are what is counted
    rows = []
    for aperture in (0.0, 100.0):
        lens = Lens(FOCUS, aperture)
        for shape, settings in (("3sigma", replace(PER_SPLAT, tau=0.0)), ("tight", replace(PER_SPLAT, tau=0.0)),
                                ("tight", PER_SPLAT)):
            pr = project(scene, cam, lens, settings)
            frags = quad_fragments(pr, cam.width, cam.height, shape)
            row = {"aperture": aperture, "shape": shape, "tau": settings.tau,
                   "gaussians_kept": int(frags.size), "fragments": float(frags.sum())}
            if shape == "tight":  # the GL renderer draws these quads: its own counts beside
                query = renderer.ctx.query(samples=True)
                with query:
                    renderer.draw(cam, lens, settings, count=True)
                row["gl_drawn"] = renderer.stats.drawn
                row["gl_fragments_blended"] = int(query.samples)
            rows.append(row)
    renderer.release()
    return {"count": n, "size": list(size), "rows": rows}


def measure_frames(sizes: tuple[int, ...], frames: int, degree: int = 3, raster: str = "quad") -> dict:
    from dofview.bench.synth import benchmark_camera, random_scene
    from dofview.lens import Lens
    from dofview.rendering import get_backend
    from dofview.rendering.gl import headless_context

    ctx = headless_context()
    cam = benchmark_camera(*FRAME_SIZE)
    rows = []
    with Progress("perf: frames", len(sizes) * len(APERTURES), delay=0.0) as bar:
        for n in sizes:
            scene = random_scene(n, degree=degree, seed=6)
            r = get_backend(raster, scene, ctx)
            for aperture in APERTURES:
                lens = Lens(FOCUS, aperture)
                row = {"count": n, "degree": degree, "aperture": aperture}
                r.forget_order()  # one fresh sort, so that its time is the one reported
                row.update(time_frames(r, cam, lens, PER_SPLAT, frames))
                row["sort_ms"] = r.stats.sort_ms
                r.draw(cam, lens, PER_SPLAT, count=True)
                row["drawn"] = r.stats.drawn
                row["bytes_per_gaussian"] = r.bytes_per_gaussian
                rows.append(row)
                bar.update(len(rows), info=f"{n} A={aperture:g}")
            r.release()
            del scene
    return {"size": list(FRAME_SIZE), "frames": frames, "raster": raster,
            "gl_renderer": ctx.info["GL_RENDERER"],
            "gl_version": ctx.info["GL_VERSION"], "rows": rows}


def measure_bottleneck(n: int, frames: int, raster: str = "quad") -> dict:
    """What limits the frame: time at A = 0 as the image shrinks (fragment work falls with the pixel
    count, vertex work stays) down to 64×36 (≈ vertex work alone), for SH degree 3 and 0."""
    from dofview.bench.synth import benchmark_camera, random_scene
    from dofview.lens import Lens
    from dofview.rendering import get_backend

    sizes = (FRAME_SIZE, (FRAME_SIZE[0] // 2, FRAME_SIZE[1] // 2), (FRAME_SIZE[0] // 4, FRAME_SIZE[1] // 4), (64, 36))
    rows = []
    with Progress("perf: bottleneck", 2 * len(sizes), delay=0.0) as bar:
        for degree in (3, 0):
            r = get_backend(raster, random_scene(n, degree=degree, seed=6))
            for w, h in sizes:
                cam = benchmark_camera(w, h)
                row = {"count": n, "degree": degree, "size": [w, h]}
                row.update(time_frames(r, cam, Lens(FOCUS, 0.0), PER_SPLAT, frames))
                rows.append(row)
                bar.update(len(rows), info=f"degree {degree} {w}×{h}")
            r.release()
    return {"rows": rows}


# ---- plots -----------------------------------------------------------------------------------
def plot(results: dict, folder: Path) -> list[Path]:
    """PNG plots of whatever ``results`` holds; returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dofview.io.atomic import atomic_output

    written = []

    def save(fig, name):
        path = folder / name
        fig.suptitle(results.get("machine", ""), fontsize=8, y=-0.04, va="top")
        with atomic_output(path) as tmp:
            fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
        plt.close(fig)
        written.append(path)

    def label(ax, xlabel: str, ylabel: str, title: str) -> None:
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_title(title)
        ax.legend()

    folder.mkdir(parents=True, exist_ok=True)
    if "load" in results:
        rows = results["load"]["rows"]
        mb = np.array([r["file_bytes"] for r in rows]) / 1e6
        fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.8))
        bottom = np.zeros(len(rows))
        for key, step in (("read_activate_s", "read + activate"), ("renderer_s", "pack + upload + link")):
            v = np.array([r[key] for r in rows])
            a.bar(range(len(rows)), v, bottom=bottom, label=step)
            bottom += v
        a.set_xticks(range(len(rows)), [f"{r['count'] / 1e6:g}M\n{m:.0f} MB" for r, m in zip(rows, mb)])
        label(a, "", "seconds", "load time, SH degree 3 .ply")
        if rows[0]["peak_rss_growth_bytes"] is not None:
            b.plot(mb, [r["peak_rss_growth_bytes"] / 1e6 for r in rows], "o-", label="peak RSS growth (VmHWM)")
        b.plot(mb, [r["traced_peak_bytes"] / 1e6 for r in rows], "s-", label="peak allocations (tracemalloc)")
        b.plot(mb, 2 * mb, "k--", label="2 × file size")
        label(b, "file size, MB", "MB", "peak host memory while loading")
        save(fig, "perf_load.png")
    if "sort" in results:
        rows = results["sort"]["rows"]
        n = [r["count"] for r in rows]
        fig, ax = plt.subplots(figsize=(5.5, 3.8))
        ax.loglog(n, [r["front_to_back_ms"] for r in rows], "o-", label="front_to_back (radix, 2×16 bit)")
        ax.loglog(n, [r["argsort_stable_ms"] for r in rows], "s-", label="np.argsort(z, stable)")
        label(ax, "Gaussians", "ms", "depth sort, one core")
        save(fig, "perf_sort.png")
    if "fragments" in results:
        rows = results["fragments"]["rows"]
        fig, ax = plt.subplots(figsize=(5.5, 3.8))
        variants = sorted({(r["shape"], r["tau"]) for r in rows}, key=lambda v: (v[0] != "3sigma", v[1]))
        for j, (shape, tau) in enumerate(variants):
            sel = [r for r in rows if (r["shape"], r["tau"]) == (shape, tau)]
            ax.bar(np.arange(len(sel)) + 0.27 * j, [r["fragments"] / 1e6 for r in sel], 0.27,
                   label=f"{'3σ squares' if shape == '3sigma' else 'tight quads'}, τ = {f'{tau * 255:.3g}/255' if tau else 0}")
        ax.set_xticks(np.arange(2) + 0.27, [f"A = {a:g}" for a in (0, 100)])
        size = results["fragments"]["size"]
        label(ax, "", "million fragments per frame", f"{results['fragments']['count']} Gaussians, {size[0]}×{size[1]}")
        save(fig, "perf_fragments.png")
    if "frames" in results:
        rows = results["frames"]["rows"]
        fig, ax = plt.subplots(figsize=(5.5, 3.8))
        for n in sorted({r["count"] for r in rows}):
            sel = [r for r in rows if r["count"] == n]
            ax.plot([r["aperture"] for r in sel], [r["wall_ms"] for r in sel], "o-",
                    label=f"{n / 1e6:g}M Gaussians")
        label(ax, "aperture A (px · scene unit)", "ms per frame",
              f"{results['frames']['gl_renderer'][:40]}, {FRAME_SIZE[0]}×{FRAME_SIZE[1]}")
        ax.set_ylim(bottom=0)
        save(fig, "perf_frames.png")
    return written


# ---- command line ----------------------------------------------------------------------------
def run(only: tuple[str, ...], quick: bool, frame_sizes: tuple[int, ...], culling_count: int = 100_000,
        raster: str = "quad") -> dict:
    """Run the chosen sub-measurements on backend ``raster`` (a key of
    :data:`dofview.rendering.BACKENDS`, or ``"auto"``; "fragments" counts the quad backend's quads
    whatever it is); ``quick`` shrinks every size for a smoke run."""
    results: dict = {"quick": quick, "machine": f"{os.cpu_count()} CPU threads, load average "
                     f"{os.getloadavg()[0]:.1f} at start"}
    if "load" in only:
        with tempfile.TemporaryDirectory(prefix="dofview-perf-") as tmp:
            results["load"] = measure_load((20_000, 50_000) if quick else (250_000, 500_000, 1_000_000), Path(tmp),
                                           raster)
    if "sort" in only:
        results["sort"] = measure_sort((10_000, 100_000) if quick else (100_000, 300_000, 1_000_000, 3_000_000),
                                       3 if quick else 7)
    if "ui" in only:
        results["ui"] = measure_ui_stall(10_000 if quick else 1_000_000, 3 if quick else 7)
    if "memory" in only:
        results["memory"] = measure_memory(1000 if quick else 100_000, raster)
    if "culling" in only:
        results["culling"] = measure_culling(5_000 if quick else culling_count, (320, 180) if quick else FRAME_SIZE,
                                             2 if quick else 5, raster)
    if "fragments" in only:
        results["fragments"] = measure_fragments(5_000 if quick else 200_000, (320, 180) if quick else FRAME_SIZE)
    if "frames" in only:
        results["frames"] = measure_frames(frame_sizes, 3 if quick else 30, raster=raster)
    if "bottleneck" in only:
        results["bottleneck"] = measure_bottleneck(5_000 if quick else frame_sizes[0], 3 if quick else 30, raster)
    return results


def main(argv: list[str] | None = None) -> int:
    from dofview.rendering import BACKENDS

    ap = argparse.ArgumentParser(prog="python -m dofview.bench.perf", description=__doc__.split("\n")[0])
    ap.add_argument("--only", default=",".join(m for m in MEASUREMENTS if m not in ("frames", "bottleneck")),
                    help=f"comma-separated sub-measurements of {', '.join(MEASUREMENTS)} (default: all but "
                         "frames and bottleneck, whose absolute times need a real GPU to mean anything)")
    ap.add_argument("--quick", action="store_true", help="small sizes: a smoke run in seconds")
    ap.add_argument("--frame-sizes", default="1000000,3000000", help="scene sizes for 'frames'")
    ap.add_argument("--culling-count", type=int, default=100_000, help="visible Gaussians for 'culling'")
    ap.add_argument("--json", type=Path, default=None, help="write all results here")
    ap.add_argument("--plots", type=Path, default=Path("docs/images"), help="folder for perf_*.png")
    ap.add_argument("--raster", default="quad", choices=["auto", *BACKENDS],
                    help="renderer backend to measure (default quad, the reference)")
    ap.add_argument("--load-child", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.load_child:
        print(json.dumps(load_child(args.load_child, args.raster)))
        return 0
    only = tuple(m.strip() for m in args.only.split(",") if m.strip())
    unknown = [m for m in only if m not in MEASUREMENTS]
    if unknown:
        ap.error(f"unknown measurement(s) {', '.join(unknown)}; choose from {', '.join(MEASUREMENTS)}")
    results = run(only, args.quick, tuple(int(s) for s in args.frame_sizes.split(",")), args.culling_count, args.raster)
    text = json.dumps(results, indent=1)
    print(text)
    if args.json:
        from dofview.io.atomic import atomic_output

        with atomic_output(args.json) as tmp:
            tmp.write_text(text)
    for path in plot(results, args.plots):
        print(f"wrote {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
