"""``dofview bench SCENE``: frame time against error of single-pass depth of field.

One run measures, on one scene and its cameras:

* frame time of every single-pass setting (warm-up, then N frames each, variants interleaved
  round-robin so that drift on a shared machine hits all of them alike): median and p90 of the
  wall time to glFinish and of the GL timer query, the depth sort timed on its own;
* the poster's table A × τ as ratios to A = 0, τ = 0 on the same camera;
* scaling with the number of Gaussians (synth.random_scene) and with resolution, with the
  fragments each frame rasterises estimated from the quads (see :func:`quad_fragments`);
* the error of every single-pass setting and of thin-lens accumulation with few samples against
  the accumulation reference (≥ 256 lens samples, accumulate.py, GL renderer at aperture 0).

Writes timing.csv, error.csv, scaling.csv, report.md and PNG plots into ``--out``.
Also runnable as ``python -m dofview.bench``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from .accumulate import accumulate
from .camera import Camera, load_cameras_json, select_camera
from .cli import _focus, _number, _tau, add_scene_args, add_view_args, camera_from_args, load_scene_arg
from .errors import DofviewError
from .focus import auto_focus
from .frame import OPACITY_NORMS, Frame, RenderSettings
from .lens import Lens
from .metrics import log_radiance_error, psnr, ssim
from .progress import Progress
from .reference import project
from .renderer import Renderer
from .scene import GaussianScene
from .sort import front_to_back
from .timing import FrameTimer, median_p90, timer_query_covers_raster
from .tonemap import Tonemap, display, encode, decode


# ---- what one run measures ---------------------------------------------------------------------
@dataclass(frozen=True)
class BenchConfig:
    """Everything a run varies. Apertures A are px·scene unit at the bench's image width."""

    focus: tuple[float | str, ...] = ("auto",)
    apertures: tuple[float, ...] = (50.0, 100.0, 200.0)      # error study
    grid_apertures: tuple[float, ...] = (0.0, 50.0, 100.0, 200.0)  # the poster's table
    taus: tuple[float, ...] = (0.0, 1 / 255, 2 / 255, 3 / 255)
    ks: tuple[float, ...] = (1 / 9, 1 / 4, 1.0)
    norms: tuple[str, ...] = OPACITY_NORMS
    ref_samples: int = 256
    acc_samples: tuple[int, ...] = (4, 8, 16, 32, 64)
    frames: int = 5
    warmup: int = 1
    counts: tuple[int, ...] = (10_000, 100_000, 1_000_000)
    count_size: tuple[int, int] = (960, 540)
    widths: tuple[int, ...] = (320, 640, 1280)
    scaling_aperture: float = 100.0
    scaling_frames: int = 2


QUICK = dict(apertures=(40.0,), grid_apertures=(0.0, 40.0), taus=(0.0, 2 / 255), ks=(1 / 4, 1.0),
             norms=("energy", "optical-depth"), ref_samples=64, acc_samples=(2, 4, 16), frames=2,
             counts=(2_000, 6_000), count_size=(160, 90), widths=(48, 96), scaling_aperture=40.0,
             scaling_frames=2)
"""--quick: a run of seconds on a tiny image, for the test suite (the reference uses 64 samples)."""


@dataclass(frozen=True)
class Job:
    """One single-pass render to time: a camera, a lens and the splatting settings."""

    view: int
    focus: float
    aperture: float
    settings: RenderSettings


def settings_variants(base: RenderSettings, cfg: BenchConfig, encoded: bool) -> list[RenderSettings]:
    """The single-pass settings studied at each aperture: k × opacity normalisation at the base τ,
    each τ at the base k and normalisation, and linear blending (display-encoded scenes only)."""
    out = [replace(base, k=k, opacity_norm=n) for k in cfg.ks for n in cfg.norms]
    out += [replace(base, tau=t) for t in cfg.taus]
    if encoded:
        out.append(replace(base, blend_linear=not base.blend_linear))
    return list(dict.fromkeys([base] + out))


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


# ---- references and error ------------------------------------------------------------------------
@dataclass
class References:
    """Thin-lens accumulation references of one camera and lens, linear RGBA frames.

    physical: linear average of the trained pinhole images (light adds on a sensor).
    encoded: average of the display-encoded pinhole images, decoded after: what display-encoded
        single-pass blending approximates (encoded scenes only; else the physical one).
    linear_blend: physical average of pinhole images blended in linear light (blend_linear).
    """

    physical: Frame
    encoded: Frame
    linear_blend: Frame | None


def pinhole_settings(base: RenderSettings, blend_linear: bool = False) -> RenderSettings:
    """Settings of the reference's pinhole renders: τ = 0 (nothing dropped); k and the opacity
    normalisation do nothing at aperture 0."""
    return replace(base, tau=0.0, blend_linear=blend_linear)


def make_references(renderer: Renderer, camera: Camera, lens: Lens, base: RenderSettings, samples: int,
                    blend_variant: bool, tick: Callable[[], None]) -> References:
    """Accumulate ``samples`` pinhole renders (GL renderer, aperture 0) over the lens disk."""
    pin = Lens(lens.focus, 0.0)
    st = pinhole_settings(base)
    encoded_sum: list[np.ndarray] = []

    def render(cam: Camera) -> Frame:
        f = renderer.render(cam, pin, st)
        enc = encode(f.rgba[..., :3]) if f.encoded else f.rgba[..., :3]
        if encoded_sum:
            encoded_sum[0] += enc
        else:
            encoded_sum.append(enc.astype(np.float64))
        tick()
        return f

    physical = accumulate(render, camera, lens, samples)
    enc_rgba = physical.rgba.copy()
    enc_avg = encoded_sum[0] / samples
    enc_rgba[..., :3] = decode(enc_avg) if physical.encoded else enc_avg
    encoded = Frame(rgba=enc_rgba.astype(np.float32), depth=physical.depth, encoded=physical.encoded)
    linear_blend = None
    if blend_variant:
        st_lin = pinhole_settings(base, blend_linear=True)

        def render_lin(cam: Camera) -> Frame:
            tick()
            return renderer.render(cam, pin, st_lin)

        linear_blend = accumulate(render_lin, camera, lens, samples)
    return References(physical=physical, encoded=encoded, linear_blend=linear_blend)


def errors(frame: Frame, ref: Frame, tm: Tonemap, hdr: bool) -> dict[str, float]:
    """PSNR and SSIM of the display images, and (HDR scenes) the log-radiance error in stops."""
    a = display(frame.rgba, frame.encoded, tm)
    b = display(ref.rgba, ref.encoded, tm)
    out = {"psnr": psnr(a, b), "ssim": ssim(a, b)}
    out["log_radiance"] = log_radiance_error(frame.rgba, ref.rgba) if hdr else float("nan")
    return out


# ---- the run ---------------------------------------------------------------------------------------
def _auto_cameras(scene_path: Path) -> Path | None:
    """``NAME_cameras.json`` beside ``NAME.ply``, as the bundled samples have, if present."""
    p = scene_path.with_name(scene_path.stem + "_cameras.json")
    return p if p.is_file() else None


def bench_cameras(args: argparse.Namespace, scene: GaussianScene) -> list[Camera]:
    """The bench's cameras: one per ``--view`` entry (comma-separated) of the cameras file."""
    views = [v.strip() for v in str(args.view).split(",") if v.strip()]
    if args.cameras is None and not (args.eye or args.target):
        args.cameras = _auto_cameras(args.scene)
    if args.cameras is None:
        return [camera_from_args(args, scene, default_size=(args.bench_width, args.bench_width * 3 // 4))]
    cams = load_cameras_json(args.cameras)
    out = []
    for v in views:
        cam = select_camera(cams, v, str(args.cameras))
        w = args.width or args.bench_width
        h = args.height or max(1, round(cam.height * w / cam.width))
        out.append(cam.resized(w, h))
    return out


def run_bench(scene: GaussianScene, cameras: list[Camera], cfg: BenchConfig, base: RenderSettings, tm: Tonemap,
              scaling: bool = True, log=print) -> dict:
    """Measure everything (see the module docstring) and return the rows for the outputs."""
    renderer = Renderer(scene)
    timer = FrameTimer(renderer.ctx)
    encoded = scene.colour_space == "srgb"
    hdr = scene.colour_space == "linear"
    variants = settings_variants(base, cfg, encoded)
    pin = pinhole_settings(base)

    focuses: list[list[float]] = []
    for cam in cameras:
        fs = []
        for f in cfg.focus:
            if f == "auto":
                f = auto_focus(renderer.render(cam, Lens(1.0, 0.0), pin))
                if f is None:
                    raise DofviewError(f"{cam.name or 'camera'}: nothing under the image centre to focus on; give --focus")
            fs.append(float(f))
        focuses.append(fs)

    jobs_by_view: list[list[Job]] = []
    for v, fs in enumerate(focuses):
        jobs = [Job(v, fs[0], a, replace(base, tau=t)) for a in cfg.grid_apertures for t in cfg.taus]
        jobs.append(Job(v, fs[0], 0.0, pin))
        jobs += [Job(v, f, a, st) for f in fs for a in cfg.apertures for st in variants]
        jobs_by_view.append(list(dict.fromkeys(jobs)))
    n_cases = sum(len(fs) for fs in focuses) * len(cfg.apertures)
    ref_renders = cfg.ref_samples * (2 if encoded else 1) + sum(cfg.acc_samples)
    steps = (sum(len(j) for j in jobs_by_view) * (cfg.frames + cfg.warmup) + n_cases * (ref_renders + len(variants)))
    if scaling:
        steps += (len(cfg.counts) * 3 + len(cfg.widths) * 2) * (cfg.scaling_frames + cfg.warmup)

    timing_rows: list[dict] = []
    error_rows: list[dict] = []
    scaling_rows: list[dict] = []
    with Progress("bench", steps) as prog:
        done = [0]

        def tick() -> None:
            done[0] += 1
            prog.update(done[0])

        # 1. frame time of every single-pass job, per view (a view change would re-sort)
        for v, jobs in enumerate(jobs_by_view):
            cam = cameras[v]
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
                        t0 = time.perf_counter()
                        acc = accumulate(lambda c: (tick(), renderer.render(c, Lens(f, 0.0), pin))[1], cam, lens, n)
                        wall = (time.perf_counter() - t0) * 1e3
                        e = errors(acc, refs.physical, tm, hdr)
                        error_rows.append({**case, "method": "accumulation", "samples": n, **_settings_cols(pin),
                                           "time_ms": n * pin_ms, "measured_ms": wall, **e,
                                           **{k + "_physical": x for k, x in e.items()}})
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
            "gl_renderer": renderer.ctx.info.get("GL_RENDERER", "?"),
            "timer_query_ok": timer_query_covers_raster(renderer.ctx), "base": base, "config": cfg,
            "scene": scene, "hdr": hdr, "encoded": encoded}


def _settings_cols(st: RenderSettings) -> dict:
    return {"tau": st.tau, "tau_255": round(st.tau * 255, 3), "k": st.k, "opacity_norm": st.opacity_norm,
            "blend_linear": st.blend_linear}


def _find(rows: list[dict], view: int, focus: float, aperture: float, st: RenderSettings) -> dict:
    cols = _settings_cols(st)
    for r in rows:
        if r["view"] == view and r["focus"] == focus and r["aperture"] == aperture and all(r[k] == x for k, x in cols.items()):
            return r
    raise KeyError((view, focus, aperture, st))


def _scaling(renderer: Renderer, scene: GaussianScene, camera: Camera, focus: float, cfg: BenchConfig,
             base: RenderSettings, timer: FrameTimer, tick, log) -> list[dict]:
    from .synth import benchmark_camera, random_scene

    a = cfg.scaling_aperture
    jobs, meta = [], []
    # Gaussians: random scenes filling the benchmark camera's view; focus mid-depth
    cam = benchmark_camera(*cfg.count_size)
    big = []
    for n in cfg.counts:
        s = random_scene(n)
        r = Renderer(s, ctx=renderer.ctx)
        big.append(r)
        f = auto_focus(r.render(cam, Lens(1.0, 0.0), pinhole_settings(base))) or 10.0
        sort_ms = median_sort_ms(s, cam, cfg.scaling_frames)
        for ap, st in ((0.0, replace(base, tau=0.0)), (a, replace(base, tau=0.0)), (a, base)):
            jobs.append((r, cam, Lens(f, ap), st))
            meta.append({"kind": "gaussians", "gaussians": n, "width": cam.width, "height": cam.height,
                         "focus": f, "aperture": ap, "sort_ms": sort_ms, "scene_obj": s, **_settings_cols(st)})
    # the Gaussian counts and the resolutions are timed in separate round-robins: a 1M-Gaussian
    # frame next to a 320-px one would let the big one's cache and memory traffic leak into it
    res = time_round_robin(jobs, timer, cfg.scaling_frames, cfg.warmup, tick)
    n_count_jobs = len(jobs)
    # resolution: the bench scene at several widths, the same physical lens (A scales with fx)
    base_w = camera.width
    sort_ms = median_sort_ms(scene, camera, cfg.scaling_frames)
    for w in cfg.widths:
        h = max(1, round(camera.height * w / camera.width))
        c = camera.resized(w, h)
        r = Renderer(scene, ctx=renderer.ctx)
        big.append(r)
        for ap, st in ((0.0, replace(base, tau=0.0)), (a * w / base_w, base)):
            jobs.append((r, c, Lens(focus, ap), st))
            meta.append({"kind": "resolution", "gaussians": scene.count, "width": w, "height": h, "focus": focus,
                         "aperture": ap, "sort_ms": sort_ms, "scene_obj": scene, **_settings_cols(st)})
    res += time_round_robin(jobs[n_count_jobs:], timer, cfg.scaling_frames, cfg.warmup, tick)
    rows = []
    for (r, c, lens, st), m, t in zip(jobs, meta, res):
        drawn, quad, ell = quad_fragments(m.pop("scene_obj"), c, lens, st)
        rows.append({**m, **t, "drawn": drawn, "quad_fragments": quad, "ellipse_fragments": ell})
    for r in big:
        r.release()
    return rows


# ---- command line ------------------------------------------------------------------------------------
def _list_of(parse: Callable[[str], object], what: str) -> Callable[[str], tuple]:
    def parse_list(text: str) -> tuple:
        items = [t.strip() for t in text.split(",") if t.strip()]
        if not items:
            raise argparse.ArgumentTypeError(f"expected a comma-separated list of {what}, got {text!r}")
        return tuple(parse(t) for t in items)
    return parse_list


def _fraction(text: str) -> float:
    """A value ≥ 0 written as a number or a fraction such as 1/9."""
    num, _, den = text.partition("/")
    value = _number(0, None, hi_open=False, what="k")(num)
    return value / _number(0, None, lo_open=True, what="denominator")(den) if den else value


_aperture = _number(0, None, hi_open=False, what="aperture")


_positive_int = _number(1, None, integer=True, what="count")


def _size(text: str) -> tuple[int, int]:
    w, _, h = text.lower().partition("x")
    return _positive_int(w), _positive_int(h)


def add_parser(sub) -> None:
    """Register ``dofview bench``."""
    p = sub.add_parser("bench", help="frame time against error of depth of field (CSV, Markdown, PNG plots)",
                       description=__doc__.split("\n\n")[0] + " Writes timing.csv, error.csv, scaling.csv, "
                                   "report.md and PNG plots into --out.")
    add_scene_args(p)
    add_view_args(p)
    p.add_argument("--out", type=Path, help="output folder (default bench_SCENE)")
    p.add_argument("--quick", action="store_true", help="a tiny run of seconds (tests): 96 px wide, 64-sample reference")
    g = p.add_argument_group("what to measure (comma-separated lists)")
    d = BenchConfig()
    g.add_argument("--focus", type=_list_of(_focus, "focus distances"), help="focus distances or 'auto' (default auto)")
    g.add_argument("--apertures", type=_list_of(_aperture, "apertures"), help="apertures A for the error study (default 50,100,200)")
    g.add_argument("--grid-apertures", type=_list_of(_aperture, "apertures"), help="apertures of the A×τ table (default 0,50,100,200)")
    g.add_argument("--taus", type=_list_of(_tau, "τ values"), help="τ values (default 0,1/255,2/255,3/255)")
    g.add_argument("--ks", type=_list_of(_fraction, "k values"), help="aperture covariance scales k (default 1/9,1/4,1)")
    g.add_argument("--norms", type=_list_of(_norm, "opacity normalisations"), help=f"opacity normalisations (default {','.join(OPACITY_NORMS)})")
    g.add_argument("--ref-samples", type=_positive_int, help=f"lens samples of the reference (default {d.ref_samples})")
    g.add_argument("--acc-samples", type=_list_of(_positive_int, "sample counts"), help="accumulation sample counts compared (default 4,8,16,32,64)")
    g.add_argument("--frames", type=_positive_int, help=f"timed frames per setting (default {d.frames})")
    g.add_argument("--warmup", type=_positive_int, default=None, help=f"warm-up rounds (default {d.warmup})")
    g.add_argument("--counts", type=_list_of(_positive_int, "Gaussian counts"), help="random-scene sizes for scaling (default 10000,100000,1000000)")
    g.add_argument("--count-size", type=_size, help="image size for the Gaussian-count scaling, WxH (default 960x540)")
    g.add_argument("--widths", type=_list_of(_positive_int, "widths"), help="image widths for resolution scaling (default 320,640,1280)")
    g.add_argument("--no-scaling", action="store_true", help="skip the scaling measurements")
    g.add_argument("--bench-width", type=_positive_int, default=480, help="image width when --width is not given (default 480)")
    g.add_argument("--exposure", type=float, default=0.0, help="display exposure in EV for PSNR/SSIM (default 0)")
    g.add_argument("--tau", type=_tau, default=RenderSettings.tau, help="base τ (default: the code's default)")
    g.add_argument("--k", type=_fraction, default=RenderSettings.k, help="base k (default: the code's default)")
    g.add_argument("--opacity-norm", type=_norm, default=RenderSettings.opacity_norm, help="base normalisation (default: the code's)")
    p.set_defaults(run=run)


def _norm(text: str) -> str:
    if text not in OPACITY_NORMS:
        raise argparse.ArgumentTypeError(f"opacity normalisation must be one of {', '.join(OPACITY_NORMS)}, got {text!r}")
    return text


def config_from_args(args: argparse.Namespace) -> BenchConfig:
    cfg = BenchConfig(**QUICK) if args.quick else BenchConfig()
    given = {"focus": args.focus, "apertures": args.apertures, "grid_apertures": args.grid_apertures,
             "taus": args.taus, "ks": args.ks, "norms": args.norms, "ref_samples": args.ref_samples,
             "acc_samples": args.acc_samples, "frames": args.frames, "warmup": args.warmup, "counts": args.counts,
             "count_size": args.count_size, "widths": args.widths}
    return replace(cfg, **{k: v for k, v in given.items() if v is not None})


def run(args: argparse.Namespace) -> int:
    from .benchreport import write_outputs
    if args.quick and args.width is None and args.height is None:
        args.bench_width = 96
    cfg = config_from_args(args)
    base = RenderSettings(tau=args.tau, k=args.k, opacity_norm=args.opacity_norm, near=args.near)
    tm = Tonemap(exposure=2.0 ** args.exposure)
    out = args.out or Path(f"bench_{args.scene.stem}")
    if out.exists() and not out.is_dir():
        raise DofviewError(f"{out}: exists and is not a folder")
    scene = load_scene_arg(args)
    cameras = bench_cameras(args, scene)
    t0 = time.perf_counter()
    result = run_bench(scene, cameras, cfg, base, tm, scaling=not args.no_scaling)
    out.mkdir(parents=True, exist_ok=True)
    command = "dofview bench " + " ".join(_bench_argv(args))
    files = write_outputs(out, result, command, time.perf_counter() - t0)
    print(f"{out}: " + ", ".join(p.name for p in files), file=sys.stderr)
    return 0


def _bench_argv(args: argparse.Namespace) -> list[str]:
    """The arguments this run was given, for the report (the scene alone when called from Python)."""
    argv = sys.argv[1:]
    if "bench" in argv:
        return argv[argv.index("bench") + 1:]
    return argv if sys.argv[0].endswith("bench.py") else [str(args.scene), "…"]


def main(argv: Sequence[str] | None = None) -> int:
    from .cli import main as cli_main

    return cli_main(["bench", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
