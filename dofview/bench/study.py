"""Depth of field against the physical thin lens on real scenes (issue 14).

Real scenes come without cameras, so the study makes its own: ``views`` look-at cameras on an arc
around the scene's robust bounds. Per view it takes two focus distances (percentiles of the
pinhole depth image) and two apertures (the A whose circle of confusion reaches a given radius in
pixels at the 5th/95th depth percentile, whichever is farther from focus), so that every scene gets
comparable blur whatever its units. Every single-pass variant is scored against the physical
truth: the linear-light average of ``ref_samples`` pinhole images over the lens disk (accumulate.py),
and timed round-robin against the others on the same frames (ratios only: a shared machine).
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from dofview.bench.runner import Steps, time_round_robin
from dofview.bench.timing import FrameTimer
from dofview.bench.variants import errors, make_references, pinhole_settings
from dofview.camera import Camera, look_at
from dofview.frame import RenderSettings
from dofview.framing import extent, guess_up, overview_camera
from dofview.lens import Lens
from dofview.progress import Progress
from dofview.rendering import Renderer
from dofview.rendering.progressive import render_lens_samples
from dofview.scene import GaussianScene
from dofview.tonemap import Tonemap

ANCHOR_KS = {"k=1/9 (CineGS)": 1 / 9, "k=1/4": 1 / 4, "k=1 (Spark)": 1.0}


@dataclass(frozen=True)
class Case:
    """One camera and lens of the study."""

    view: int
    camera: Camera
    lens: Lens
    focus_pct: float
    coc_px: float


def study_views(scene: GaussianScene, n: int, width: int, height: int, fov_deg: float = 50.0,
                arc_deg: float = 60.0) -> list[Camera]:
    """``n`` cameras on a horizontal arc of ``arc_deg``: the viewer's overview camera (framing.py:
    robust box, guessed up) turned about the world up through the point it looks at."""
    up = guess_up(scene).vector
    base = overview_camera(scene, width, height, fov_deg, up)
    eye, fwd = base.centre, base.forward
    centre, _ = extent(scene)
    pivot = eye + fwd * float((centre - eye) @ fwd)
    cams = []
    for i in range(n):
        az = math.radians(arc_deg) * ((i / (n - 1)) - 0.5) if n > 1 else 0.0
        off = eye - pivot
        # Rodrigues' rotation of the eye about ``up`` through the pivot
        rot = off * math.cos(az) + np.cross(up, off) * math.sin(az) + up * float(up @ off) * (1 - math.cos(az))
        cams.append(look_at(pivot + rot, pivot, width, height, fov_deg, up=tuple(up)))
    return cams


def depth_percentiles(frame, pcts) -> list[float]:
    """Coverage-weighted percentiles of the depth image (scene units) of a pinhole frame."""
    a = frame.rgba[..., 3].ravel().astype(np.float64)
    z = frame.depth.ravel().astype(np.float64)
    keep = (a > 0.05) & (z > 0)
    z, a = z[keep], a[keep]
    order = np.argsort(z)
    cw = np.cumsum(a[order]) / a.sum()
    return [float(z[order][np.searchsorted(cw, p / 100.0)]) for p in pcts]


def study_cases(renderer: Renderer, cameras: list[Camera], focus_pcts=(30.0, 70.0),
                cocs=(6.0, 16.0)) -> list[Case]:
    """Two focus distances × two apertures per camera (see the module docstring)."""
    out = []
    pin = pinhole_settings(RenderSettings())
    for v, cam in enumerate(cameras):
        fr = renderer.render(cam, Lens(1.0, 0.0), pin)
        z5, z95, *zf = depth_percentiles(fr, (5.0, 95.0, *focus_pcts))
        for fp, f in zip(focus_pcts, zf):
            span = max(abs(1 / z5 - 1 / f), abs(1 / z95 - 1 / f))
            for c in cocs:
                out.append(Case(v, cam, Lens(f, 2.0 * c / span), fp, c))
    return out


def study_variants() -> dict[str, RenderSettings]:
    """The single-pass settings of the table: pinhole, the anchors (per-splat blur, energy
    normalisation, the reference rasteriser's α ≥ 1/255 cut), the default (sliced depth of field),
    and the per-splat mode with the mass-conserving cut and with the disk kernel."""
    anchor = RenderSettings(tau=1 / 255, k=1 / 4, opacity_norm="energy", blend_linear=False, cut="drop", dof="splat")
    out = {"pinhole": anchor}
    out.update({name: replace(anchor, k=k) for name, k in ANCHOR_KS.items()})
    out["default"] = RenderSettings()
    out["splat, conserve cut"] = replace(anchor, cut="conserve")
    out["splat, disk kernel"] = replace(anchor, kernel="disk")
    return out


def run_study(renderer: Renderer, cases: list[Case], variants: dict[str, RenderSettings], ref_samples: int,
              acc_samples=(1, 2, 4, 8, 16, 32, 64), frames: int = 3, tm: Tonemap | None = None) -> list[dict]:
    """Rows of (case, method, samples, psnr, ssim, time_ratio) for every variant and every count of
    the progressive thin lens (the viewer's stage of n sub-aperture passes, rendering/progressive.py,
    a separate estimate from the reference even at ``ref_samples``). ``time_ratio``
    is the median frame time over that of the pinhole frame at the default τ on the same camera,
    all timed round-robin; accumulation counts n frames of the base settings (a stage's passes).
    The variant named
    "pinhole" is drawn at aperture 0."""
    tm = tm or Tonemap()
    timer = FrameTimer(renderer.ctx)
    hdr = renderer.scene.colour_space == "linear"
    base = RenderSettings()
    rows: list[dict] = []
    steps = len(cases) * (ref_samples + len(acc_samples) + len(variants) * (frames + 2) + 2 * (frames + 1))
    with Progress("study", steps) as prog:
        tick = Steps(prog)
        for i, case in enumerate(cases):
            cam, lens = case.camera, case.lens
            label = f"case {i + 1}/{len(cases)} (CoC {case.coc_px:g} px)"
            pin = Lens(lens.focus, 0.0)
            lenses = [pin if name == "pinhole" else lens for name in variants]
            jobs = [(renderer, cam, pin, replace(base, dof="splat")), (renderer, cam, lens, base)]
            jobs += [(renderer, cam, ln, st) for ln, st in zip(lenses, variants.values())]
            tick.stage(f"{label}: timing frame", len(jobs) * (frames + 1))
            times = time_round_robin(jobs, timer, frames, 1, tick)
            pin_ms = times[0]["wall_med_ms"]
            pass_ratio = times[1]["wall_med_ms"] / pin_ms  # one pass of a stage: a frame of the base settings
            tick.stage(f"{label}: truth lens sample", ref_samples)
            truth = make_references(renderer, cam, lens, base, ref_samples, False, tick).physical
            info = {"view": case.view, "focus": lens.focus, "aperture": lens.aperture,
                    "focus_pct": case.focus_pct, "coc_px": case.coc_px}
            tick.stage(f"{label}: progressive lens stage", len(acc_samples))
            for n in acc_samples:
                e = errors(render_lens_samples(renderer, cam, lens, base, n), truth, tm, hdr)
                tick()
                rows.append({**info, "method": f"accumulation {n}", "samples": n, **e, "time_ratio": n * pass_ratio})
            tick.stage(f"{label}: single-pass variant", len(variants))
            for (name, st), ln, t in zip(variants.items(), lenses, times[2:]):
                e = errors(renderer.render(cam, ln, st), truth, tm, hdr)
                tick()
                rows.append({**info, "method": name, "samples": 1, **e, "time_ratio": t["wall_med_ms"] / pin_ms})
    return rows


def summarise(rows: list[dict]) -> dict[str, dict[str, float]]:
    """Per method: mean PSNR (of per-case PSNR), mean SSIM, mean time ratio."""
    out: dict[str, dict[str, float]] = {}
    for name in dict.fromkeys(r["method"] for r in rows):
        rs = [r for r in rows if r["method"] == name]
        out[name] = {k: float(np.mean([r[k] for r in rs])) for k in ("psnr", "ssim", "time_ratio")}
    return out


def pareto(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The (time, PSNR) points no other point beats on both (faster or as fast, and better)."""
    front, best = [], -math.inf
    for t, p in sorted(points, key=lambda x: (x[0], -x[1])):
        if p > best:
            front.append((t, p))
            best = p
    return front


def plot_study(path, name: str, summary: dict[str, dict[str, float]], ref_samples: int) -> None:
    """PSNR against the physical truth over frame time (ratio to the pinhole frame): the progressive
    accumulation curve, the single-pass variants and the Pareto front of all of them."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    acc = [(v["time_ratio"], v["psnr"], m) for m, v in summary.items() if m.startswith("accumulation")]
    ax.plot([a[0] for a in acc], [a[1] for a in acc], "o-", color="black", ms=3,
            label="progressive thin lens (stage of n passes)")
    for t, p, m in acc:
        ax.annotate(m.split()[1], (t, p), textcoords="offset points", xytext=(3, -10), fontsize=7)
    single = [(v["time_ratio"], v["psnr"], m) for m, v in summary.items() if not m.startswith("accumulation")]
    for (t, p, m), mk in zip(single, "sv^D<>ph*"):
        style = {"ms": 13, "mfc": "none", "mew": 2, "color": "red"} if m == "default" else {"ms": 7}
        ax.plot([t], [p], mk if m != "default" else "o", label=m, **style)
    front = pareto([(t, p) for t, p, _ in acc + single])
    ax.step([f[0] for f in front], [f[1] for f in front], where="post", color="grey", alpha=0.6, lw=3, zorder=0,
            label="Pareto front")
    ax.set_xscale("log")
    ax.set_xlabel("frame time / pinhole frame (τ default), llvmpipe")
    ax.set_ylabel(f"PSNR vs physical thin lens ({ref_samples} samples), dB")
    ax.set_title(name)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def largest_blur_ratio(renderer: Renderer, cases: list[Case], frames: int = 7) -> dict:
    """Median frame time at the largest aperture of ``cases`` per distinct camera and focus (their
    largest CoC in px; default settings, and the per-splat mode's k = 1/4) over the pinhole frame at
    the default τ, timed round-robin: a cost that means the same blur whatever the scene's units."""
    timer = FrameTimer(renderer.ctx)
    prev = study_variants()["k=1/4"]
    out = {"default": [], "splat k=1/4": []}
    largest: dict[tuple[int, float], Case] = {}
    for c in cases:
        key = (c.view, c.lens.focus)
        if key not in largest or c.lens.aperture > largest[key].lens.aperture:
            largest[key] = c
    for c in largest.values():
        jobs = [(renderer, c.camera, Lens(c.lens.focus, 0.0), prev),
                (renderer, c.camera, c.lens, RenderSettings()),
                (renderer, c.camera, c.lens, prev)]
        t = [x["wall_med_ms"] for x in time_round_robin(jobs, timer, frames, 1, lambda: None)]
        out["default"].append(t[1] / t[0])
        out["splat k=1/4"].append(t[2] / t[0])
    return {k: float(np.mean(v)) for k, v in out.items()}


def table_lines(name: str, summary: dict[str, dict[str, float]], count: int, n_cases: int) -> list[str]:
    """The issue's table for one scene: PSNR / SSIM / frame-time ratio per method."""
    lines = [f"**{name}** ({count:,} Gaussians, {n_cases} cases)", "",
             "| method | PSNR (dB) | SSIM | frame time / pinhole |", "|---|---|---|---|"]
    for m, v in summary.items():
        lines.append(f"| {m} | {v['psnr']:.2f} | {v['ssim']:.4f} | {v['time_ratio']:.2f} |")
    return lines + [""]


def run_cli(args, scene: GaussianScene, out: Path, command: str) -> int:
    """``dofview bench SCENE --views N``: the study on one scene, into ``out`` (bench/cli.py has
    loaded the scene and checked ``out``). One renderer (``--raster``) serves every step."""
    from dofview.bench.report import write_csv
    from dofview.rendering import get_backend

    w = args.width or args.bench_width
    h = args.height or w * 3 // 4
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    renderer = get_backend(args.raster, scene)
    try:
        cases = study_cases(renderer, study_views(scene, args.views, w, h), args.focus_pct, args.coc_px)
        ref = args.ref_samples or 128
        acc = tuple(n for n in (1, 2, 4, 8, 16, 32, 64, 128, 256) if n <= ref)
        rows = run_study(renderer, cases, study_variants(), ref, acc, args.frames or 3,
                         Tonemap(exposure=args.exposure))
        fixed = largest_blur_ratio(renderer, cases)
    finally:
        renderer.release()
    summary = summarise(rows)
    write_csv(out / "study.csv", rows)
    name = args.scene.name
    if not args.no_plots:
        plot_study(out / "study.png", name, summary, ref)
    lines = [f"# Depth of field against the physical thin lens: {name}", "",
             (f"`{command}` ({time.perf_counter() - t0:.0f} s); {w}×{h} px, {args.views} views × focus at depth "
              f"percentiles {', '.join(f'{p:g}' for p in args.focus_pct)} × CoC "
              f"{', '.join(f'{c:g}' for c in args.coc_px)} px; truth: {ref} lens samples, linear light; "
              f"renderer {renderer.name}, llvmpipe timings as ratios."), ""]
    lines += table_lines(name, summary, scene.count, len(cases))
    lines.append(f"Largest blur ({max(args.coc_px):g} px CoC): frame time / pinhole at the default τ: default "
                 f"{fixed['default']:.2f}×, "
                 f"per-splat k = 1/4 {fixed['splat k=1/4']:.2f}× (mean over views and focus distances)")
    (out / "study.md").write_text("\n".join(lines) + "\n")
    print(f"{out}: study.csv, study.md" + ("" if args.no_plots else ", study.png"), file=sys.stderr)
    return 0
