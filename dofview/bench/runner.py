"""``dofview bench SCENE``: frame time against error of single-pass depth of field.

One run measures, on one scene and its cameras:

* frame time of every single-pass setting (warm-up, then N frames each, variants interleaved
  round-robin so that drift on a shared machine hits all of them alike): median and p90 of the
  wall time to glFinish and of the GL timer query, the depth sort timed on its own;
* the poster's table A × τ as ratios to A = 0, τ = 0 on the same camera;
* scaling with the number of Gaussians (synth.random_scene) and with resolution, with the
  fragments each frame rasterises estimated from the quads (see :func:`quad_fragments`);
* the error of every single-pass setting and of thin-lens accumulation with few samples against
  the accumulation reference (``ref_samples`` lens samples, accumulate.py, GL renderer at aperture 0),
  at apertures chosen from the scene by the blur they make in pixels (BenchConfig.with_apertures).

Writes timing.csv, error.csv, scaling.csv, report.md and PNG plots into ``--out``.
The command line is :mod:`dofview.bench.cli`; also runnable as ``python -m dofview.bench``.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Callable, Sequence

import numpy as np

from dofview.bench.timing import FrameTimer, median_p90, timer_query_covers_raster
from dofview.bench.variants import (
    BenchConfig,
    Job,
    errors,
    make_references,
    pinhole_settings,
    settings_variants,
)
from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.lens import Lens, aperture_for_blur
from dofview.progress import Progress
from dofview.rendering import Renderer, get_backend
from dofview.rendering.accumulate import accumulate
from dofview.rendering.focus import auto_focus, depth_range
from dofview.rendering.footprint import project
from dofview.rendering.depth_order import front_to_back
from dofview.scene import GaussianScene
from dofview.tonemap import Tonemap


def quad_fragments(scene: GaussianScene, camera: Camera, lens: Lens, settings: RenderSettings) -> tuple[int, float, float]:
    """Estimated (Gaussians drawn, quad fragments, ellipse fragments) of one frame.

    Computed on the CPU from reference.project's per-Gaussian quantities (the same footprint,
    opacity and support bound the vertex shader computes), with the shader's quad: the ellipse's
    bounding rectangle along its eigen-axes plus half a pixel. Quad fragments are what the
    rasteriser shades; ellipse fragments (area where α ≥ τ) are what blends. Each is clipped to
    the image by the fraction of its axis-aligned box inside it (an estimate for rotated quads).
    """
    pr = project(scene, camera, lens, settings)
    sxx, sxy, syy = pr["cov"].T
    r2, p = pr["r2"], pr["mean2d"]
    ext = np.sqrt(r2[:, None] * np.stack([sxx, syy], 1))
    w, h = camera.width, camera.height
    on = (p[:, 0] + ext[:, 0] >= 0) & (p[:, 0] - ext[:, 0] <= w) & (p[:, 1] + ext[:, 1] >= 0) & (p[:, 1] - ext[:, 1] <= h)
    sxx, sxy, syy, r2, p = sxx[on], sxy[on], syy[on], r2[on], p[on]
    det = sxx * syy - sxy * sxy
    half_diff = 0.5 * (sxx - syy)
    l1 = 0.5 * (sxx + syy) + np.sqrt(half_diff ** 2 + sxy ** 2)
    l2 = det / l1
    e1 = np.where((half_diff >= 0)[:, None], np.stack([l1 - syy, sxy], 1), np.stack([sxy, l1 - sxx], 1))
    norm = np.linalg.norm(e1, axis=1, keepdims=True)
    e1 = np.where(norm > 0, e1 / np.maximum(norm, 1e-300), [1.0, 0.0])
    r = np.sqrt(r2)
    a1, a2 = r * np.sqrt(l1) + 0.5, r * np.sqrt(l2) + 0.5
    half = np.stack([a1 * np.abs(e1[:, 0]) + a2 * np.abs(e1[:, 1]), a1 * np.abs(e1[:, 1]) + a2 * np.abs(e1[:, 0])], 1)
    inside = np.ones(len(p))
    for axis, size in ((0, w), (1, h)):
        lo, hi = p[:, axis] - half[:, axis], p[:, axis] + half[:, axis]
        inside *= np.clip(np.minimum(hi, size) - np.maximum(lo, 0), 0, None) / np.maximum(hi - lo, 1e-12)
    quad = 4.0 * a1 * a2 * inside
    ellipse = math.pi * r2 * np.sqrt(np.maximum(det, 0.0)) * inside
    return int(on.sum()), float(quad.sum()), float(ellipse.sum())


def median_sort_ms(scene: GaussianScene, camera: Camera, reps: int) -> float:
    """Median time of the depth sort (sort.front_to_back) for ``camera``, ms."""
    times = []
    for _ in range(max(reps, 1)):
        t0 = time.perf_counter()
        front_to_back(scene.means, camera)
        times.append((time.perf_counter() - t0) * 1e3)
    return float(np.median(times))


def time_round_robin(jobs: Sequence[tuple[Renderer, Camera, Lens, RenderSettings]], timer: FrameTimer,
                     frames: int, warmup: int, tick: Callable[[], None]) -> list[dict]:
    """Time each job ``frames`` times after ``warmup`` rounds, interleaved: every round draws every
    job once, starting one job later each round. Returns per job wall/GPU median and p90 (ms)."""
    walls: list[list[float]] = [[] for _ in jobs]
    gpus: list[list[float]] = [[] for _ in jobs]
    n = len(jobs)
    for rnd in range(warmup + frames):
        for j in [(i + rnd) % n for i in range(n)]:
            r, cam, lens, st = jobs[j]
            wall, gpu = timer(lambda: r.draw(cam, lens, st))
            if rnd >= warmup:
                walls[j].append(wall)
                gpus[j].append(gpu)
            tick()
    out = []
    for w, g in zip(walls, gpus):
        wm, wp = median_p90(w)
        gm, gp = median_p90(g)
        out.append({"wall_med_ms": wm, "wall_p90_ms": wp, "gpu_med_ms": gm, "gpu_p90_ms": gp})
    return out


class Steps:
    """Progress of a run made of stages: ``steps.stage("reference A=12", 256)`` then one call per
    step; the progress line names the stage and counts its steps, so the first minutes of a long
    run are not silent. ``weight``: the step's cost in pinhole frames at the bench's size, for the
    ETA (a 200k-Gaussian frame costs more than a 40k one)."""

    def __init__(self, prog: Progress) -> None:
        self.prog, self.done = prog, 0
        self.stage("starting", 0)

    def stage(self, name: str, count: int, weight: int = 1) -> None:
        self.name, self.count, self.i, self.weight = name, count, 0, weight

    def __call__(self) -> None:
        self.i += 1
        self.done += self.weight
        self.prog.update(self.done, info=f"{self.name} {self.i}/{self.count}")


# ---- the run ---------------------------------------------------------------------------------------
def run_bench(scene: GaussianScene, cameras: list[Camera], cfg: BenchConfig, base: RenderSettings, tm: Tonemap,
              scaling: bool = True, log=print) -> dict:
    """Measure everything (see the module docstring) and return the rows for the outputs.

    Apertures that ``cfg`` leaves to the scene are chosen from the first view's pinhole image
    (BenchConfig.with_apertures); the result's ``blur_px`` maps every aperture studied to its
    largest blur in that view (px)."""
    renderer = get_backend(cfg.raster, scene)
    timer = FrameTimer(renderer.ctx)
    encoded = scene.colour_space == "srgb"
    hdr = scene.colour_space == "linear"
    pin = pinhole_settings(base)

    focuses: list[list[float]] = []
    for v, cam in enumerate(cameras):
        pinhole = renderer.render(cam, Lens(1.0, 0.0), pin)
        if v == 0:
            depths = depth_range(pinhole)
        fs = []
        for f in cfg.focus:
            if f == "auto":
                f = auto_focus(pinhole)
                if f is None:
                    raise DofviewError(f"{cam.name or 'camera'}: nothing under the image centre to focus on; give --focus")
            fs.append(float(f))
        focuses.append(fs)
    if depths is None:
        raise DofviewError(f"{cameras[0].name or 'camera'}: the view shows nothing of the scene")
    chosen = cfg.apertures is None
    cfg = cfg.with_apertures(cameras[0].width, focuses[0][0], depths)
    px_per_a = 1.0 / aperture_for_blur(1.0, focuses[0][0], *depths)
    blur_px = {a: a * px_per_a for a in (*cfg.grid_apertures, *cfg.apertures)}
    variants = settings_variants(base, cfg, encoded)

    jobs_by_view: list[list[Job]] = []
    for v, fs in enumerate(focuses):
        jobs = [Job(v, fs[0], a, replace(base, tau=t, dof="splat")) for a in cfg.grid_apertures for t in cfg.taus]
        jobs.append(Job(v, fs[0], 0.0, pin))
        jobs += [Job(v, f, a, st) for f in fs for a in cfg.apertures for st in variants]
        jobs_by_view.append(list(dict.fromkeys(jobs)))
    n_cases = sum(len(fs) for fs in focuses) * len(cfg.apertures)
    ref_renders = cfg.ref_samples * (2 if encoded else 1)
    steps = (sum(len(j) for j in jobs_by_view) * (cfg.frames + cfg.warmup)
             + n_cases * (ref_renders + sum(cfg.acc_samples) + len(variants)))
    if scaling:
        steps += sum(w * n for w, n in _scaling_weights(cameras[0], scene.count, cfg))

    timing_rows: list[dict] = []
    error_rows: list[dict] = []
    scaling_rows: list[dict] = []
    with Progress("bench", steps) as prog:
        tick = Steps(prog)

        # 1. frame time of every single-pass job, per view (a view change would re-sort)
        for v, jobs in enumerate(jobs_by_view):
            cam = cameras[v]
            tick.stage(f"timing view {v}: {len(jobs)} settings, frame", len(jobs) * (cfg.frames + cfg.warmup))
            res = time_round_robin([(renderer, cam, Lens(j.focus, j.aperture), j.settings) for j in jobs],
                                   timer, cfg.frames, cfg.warmup, tick)
            sort_ms = median_sort_ms(scene, cam, cfg.frames)
            for j, r in zip(jobs, res):
                drawn, quad, ell = quad_fragments(scene, cam, Lens(j.focus, j.aperture), j.settings)
                timing_rows.append({"view": v, "camera": cam.name, "width": cam.width, "height": cam.height,
                                    "gaussians": scene.count, "focus": j.focus, "aperture": j.aperture,
                                    **_settings_cols(j.settings), **r, "sort_ms": sort_ms, "drawn": drawn,
                                    "quad_fragments": quad, "ellipse_fragments": ell})

        # 2. error against the accumulation reference, on the same cameras and lenses
        for v, fs in enumerate(focuses):
            cam = cameras[v]
            pin_ms = _find(timing_rows, v, fs[0], 0.0, pin)["wall_med_ms"]
            for f in fs:
                for a in cfg.apertures:
                    lens = Lens(f, a)
                    tick.stage(f"view {v} A={a:.3g} ({blur_px[a]:.3g} px): reference lens sample", ref_renders)
                    refs = make_references(renderer, cam, lens, base, cfg.ref_samples, encoded, tick)
                    case = {"view": v, "camera": cam.name, "focus": f, "aperture": a}
                    # how far each blend space's own reference sits from the physical one: the
                    # error floor of any single pass blending in that space
                    floors = [("encoded-reference", refs.encoded, False)] if encoded else []
                    if refs.linear_blend is not None:
                        floors.append(("linear-blend-reference", refs.linear_blend, True))
                    for name, ref, lin in floors:
                        e = errors(ref, refs.physical, tm, hdr)
                        error_rows.append({**case, "method": name, "samples": cfg.ref_samples,
                                           **_settings_cols(pinhole_settings(base, lin)), "time_ms": float("nan"),
                                           "measured_ms": float("nan"), **e,
                                           **{k + "_physical": x for k, x in e.items()}})
                    for n in cfg.acc_samples:
                        tick.stage(f"view {v} A={a:.3g}: accumulation ×{n}, sample", n)
                        t0 = time.perf_counter()
                        acc = accumulate(lambda c: (tick(), renderer.render(c, Lens(f, 0.0), pin))[1], cam, lens, n)
                        wall = (time.perf_counter() - t0) * 1e3
                        e = errors(acc, refs.physical, tm, hdr)
                        error_rows.append({**case, "method": "accumulation", "samples": n, **_settings_cols(pin),
                                           "time_ms": n * pin_ms, "measured_ms": wall, **e,
                                           **{k + "_physical": x for k, x in e.items()}})
                    tick.stage(f"view {v} A={a:.3g}: single-pass setting", len(variants))
                    for st in variants:
                        fr = renderer.render(cam, lens, st)
                        tick()
                        matched = refs.linear_blend if st.blend_linear and refs.linear_blend else refs.encoded
                        e = errors(fr, matched, tm, hdr)
                        ep = errors(fr, refs.physical, tm, hdr)
                        error_rows.append({**case, "method": "single-pass", "samples": 1, **_settings_cols(st),
                                           "time_ms": _find(timing_rows, v, f, a, st)["wall_med_ms"],
                                           "measured_ms": float("nan"), **e,
                                           **{k + "_physical": x for k, x in ep.items()}})

        # 3. scaling with the number of Gaussians and with resolution
        if scaling:
            scaling_rows = _scaling(renderer, scene, cameras[0], focuses[0][0], cfg, base, timer, tick, log)
    return {"timing": timing_rows, "error": error_rows, "scaling": scaling_rows,
            "gl_renderer": renderer.ctx.info.get("GL_RENDERER", "?"), "backend": renderer.name,
            "timer_query_ok": timer_query_covers_raster(renderer.ctx), "base": base, "config": cfg,
            "blur_px": blur_px, "apertures_chosen": chosen, "depth_range": depths, "scene": scene, "hdr": hdr, "encoded": encoded}


def _settings_cols(st: RenderSettings) -> dict:
    """A row's settings columns: RenderSettings.to_dict, and τ in 255ths for reading."""
    return {**st.to_dict(), "tau_255": round(st.tau * 255, 3)}


def _find(rows: list[dict], view: int, focus: float, aperture: float, st: RenderSettings) -> dict:
    cols = _settings_cols(st)
    for r in rows:
        if r["view"] == view and r["focus"] == focus and r["aperture"] == aperture and all(r[k] == x for k, x in cols.items()):
            return r
    raise KeyError((view, focus, aperture, st))


def _scaling_weights(camera: Camera, count: int, cfg: BenchConfig) -> list[tuple[int, int]]:
    """(weight, steps) of the two scaling round-robins (Gaussian counts, then resolutions): a step's
    weight is its mean cost in frames of ``camera`` on the bench scene of ``count`` Gaussians,
    guessed as the pixel ratio times the Gaussian ratio; it only steers the ETA."""
    px = camera.width * camera.height
    w, h = cfg.count_size
    counts = [w * h / px * max(1.0, n / count) for n in cfg.counts]
    widths = [wd * wd * camera.height / camera.width / px for wd in cfg.widths]
    rounds = cfg.scaling_frames + cfg.warmup
    return [(max(1, round(float(np.mean(c)))), len(c) * k * rounds) for c, k in ((counts, 3), (widths, 2))]


def _scaling(renderer: Renderer, scene: GaussianScene, camera: Camera, focus: float, cfg: BenchConfig,
             base: RenderSettings, timer: FrameTimer, tick: Steps, log) -> list[dict]:
    from dofview.bench.synth import benchmark_camera, random_scene

    a = cfg.scaling_aperture
    (w_counts, n_counts), (w_widths, n_widths) = _scaling_weights(camera, scene.count, cfg)
    jobs, meta = [], []
    # Gaussians: random scenes filling the benchmark camera's view; focus mid-depth
    cam = benchmark_camera(*cfg.count_size)
    big = []
    for n in cfg.counts:
        s = random_scene(n)
        r = type(renderer)(s, ctx=renderer.ctx)
        big.append(r)
        f = auto_focus(r.render(cam, Lens(1.0, 0.0), pinhole_settings(base))) or 10.0
        sort_ms = median_sort_ms(s, cam, cfg.scaling_frames)
        for ap, st in ((0.0, replace(base, tau=0.0)), (a, replace(base, tau=0.0)), (a, base)):
            jobs.append((r, cam, Lens(f, ap), st))
            meta.append({"kind": "gaussians", "gaussians": n, "width": cam.width, "height": cam.height,
                         "focus": f, "aperture": ap, "sort_ms": sort_ms, "scene_obj": s, **_settings_cols(st)})
    # the Gaussian counts and the resolutions are timed in separate round-robins: a 1M-Gaussian
    # frame next to a 320-px one would let the big one's cache and memory traffic leak into it
    tick.stage(f"scaling {', '.join(f'{n:,}' for n in cfg.counts)} Gaussians: frame", n_counts, w_counts)
    res = time_round_robin(jobs, timer, cfg.scaling_frames, cfg.warmup, tick)
    n_count_jobs = len(jobs)
    # resolution: the bench scene at several widths, the same physical lens (A scales with fx),
    # the study's middle aperture
    a = cfg.apertures[len(cfg.apertures) // 2]
    base_w = camera.width
    sort_ms = median_sort_ms(scene, camera, cfg.scaling_frames)
    for w in cfg.widths:
        h = max(1, round(camera.height * w / camera.width))
        c = camera.resized(w, h)
        r = type(renderer)(scene, ctx=renderer.ctx)
        big.append(r)
        for ap, st in ((0.0, replace(base, tau=0.0)), (a * w / base_w, base)):
            jobs.append((r, c, Lens(focus, ap), st))
            meta.append({"kind": "resolution", "gaussians": scene.count, "width": w, "height": h, "focus": focus,
                         "aperture": ap, "sort_ms": sort_ms, "scene_obj": scene, **_settings_cols(st)})
    tick.stage(f"scaling widths {', '.join(map(str, cfg.widths))}: frame", n_widths, w_widths)
    res += time_round_robin(jobs[n_count_jobs:], timer, cfg.scaling_frames, cfg.warmup, tick)
    rows = []
    for (r, c, lens, st), m, t in zip(jobs, meta, res):
        drawn, quad, ell = quad_fragments(m.pop("scene_obj"), c, lens, st)
        rows.append({**m, **t, "drawn": drawn, "quad_fragments": quad, "ellipse_fragments": ell})
    for r in big:
        r.release()
    return rows


