"""Sliced depth of field (``--dof sliced``, rendering/sliced.py) measured: against the physical thin
lens next to the published per-splat anchors, and its frame time against the pinhole frame.

    python -m dofview.bench.sliced_study quality --scenes DIR [--width 240] [--samples 64] [--only NAME]
        [--rule KEY=V[,KEY=V]] ... [--markdown TABLE.md] [--figure PNG]
    python -m dofview.bench.sliced_study timing SCENE... [--width 640 --height 360] [--reps 3]
        [--rule KEY=V[,KEY=V]] ... [--places DIR]
    python -m dofview.bench.sliced_study passes SCENE... [--width 640 --height 360] [--reps 3]
        [--places DIR] [--raster quad|compute] [--figure PNG]

quality: per scene (the five real ones; the views from inside the shared places,
dofview/bench/places: corridor_1 … showroom_2, focused on their subjects, blur between the 20th and
95th depth percentiles; "indoor" and "near_wall", synthetic rooms seen from inside) and case
(largest blur in view 8 and 16 px, focus at the median depth; for the near wall its CoC, 60 or
120 px at 240 px wide) one tab-separated line per method: PSNR and SSIM of the display image
against the linear-light average of ``--samples`` pinhole images over the lens disk, and their
difference to the best anchor (per-splat k = 1/9, 1/4, 1, energy normalisation, τ = 1/255), and
the layers drawn. Methods: the anchors, then the sliced mode with the default rule
(slices.SLICE_RULE) and with each ``--rule`` (fields of SliceRule changed, e.g. ``growth=1.3`` or
``limit=4,spread=0``). ``--figure``: truth | best anchor | sliced of the first scene's last case.

timing: per scene (a file, or with ``--places DIR`` a place view such as corridor_1, at its own
camera and lenses) backend and case (A = 100 px·unit; largest blur in view 16 px) the median
frame time of the per-splat and the sliced mode (each rule) over interleaved draws, as ratios to
the pinhole frame's (A = 0, per-splat, default τ: one splatting pass), and the sliced mode's GPU
memory per megapixel.

passes: for the same scenes and cases, where the sliced frame's time goes: each kind of pass
(Renderer.sliced_pass_times: the GL waited for after each) in ms, the median over ``--reps``
frames, beside the pinhole frame and the sliced frame drawn without the waits. ``--figure``: a PNG
of the kinds as stacked bars in units of the pinhole frame.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import fields, replace
from pathlib import Path

import numpy as np

from dofview.bench.places import place_views
from dofview.bench.primitives import Parts
from dofview.bench.study import ANCHOR_KS, depth_percentiles, study_views
from dofview.bench.synth import room_scene
from dofview.bench.variants import errors, make_references, pinhole_settings
from dofview.camera import Camera, look_at
from dofview.frame import Frame, RenderSettings
from dofview.lens import Lens, aperture_for_blur
from dofview.rendering import Renderer, get_backend
from dofview.rendering.slices import SLICE_RULE, SliceRule
from dofview.scene import GaussianScene
from dofview.tonemap import Tonemap
from dofview.tonemap.display import display

SCENES = ("two_planes.ply", "burger.ply", "guitar.compressed.ply", "biker.spz", "tap.spz")
ANCHOR = RenderSettings(tau=1 / 255, k=1 / 4, opacity_norm="energy", cut="drop", dof="splat")
SLICED = RenderSettings(dof="sliced")
PINHOLE = RenderSettings(dof="splat")  # at A = 0: one splatting pass with the default τ


def parse_rule(text: str) -> SliceRule:
    """A SliceRule from ``KEY=V[,KEY=V]`` (fields of SliceRule changed from the default rule)."""
    values = {}
    for part in text.split(","):
        key, _, value = part.partition("=")
        values[key.strip()] = float(value)
    return replace(SLICE_RULE, **values)


def rule_name(rule: SliceRule) -> str:
    """'sliced', with the fields of ``rule`` that differ from the default rule."""
    changed = [f"{f.name}={getattr(rule, f.name):g}" for f in fields(SliceRule)
               if getattr(rule, f.name) != getattr(SLICE_RULE, f.name)]
    return "sliced" + (f" ({', '.join(changed)})" if changed else "")


def sliced_render(renderer: Renderer, camera: Camera, lens: Lens, rule: SliceRule) -> Frame:
    """The sliced mode with ``rule`` (the renderer's slicing set for the draw, then restored)."""
    renderer.slice_rule = rule
    try:
        return renderer.render(camera, lens, SLICED)
    finally:
        renderer.slice_rule = None


# ---- the cases --------------------------------------------------------------------------------------
def cases_for(renderer: Renderer, camera: Camera, blurs=(8.0, 16.0), focus_pct: float = 50.0,
              span_pcts: tuple[float, float] = (5.0, 95.0)) -> list[Lens]:
    """Lenses focused at the ``focus_pct`` depth percentile of the pinhole image whose largest blur
    between the ``span_pcts`` depth percentiles is each of ``blurs`` px (lens.aperture_for_blur).
    Indoors the near-camera Gaussians lie below the span and get far more blur."""
    fr = renderer.render(camera, Lens(1.0, 0.0), pinhole_settings(RenderSettings()))
    near, far, zf = depth_percentiles(fr, (*span_pcts, focus_pct))
    return [Lens(zf, aperture_for_blur(b, zf, near, far)) for b in blurs]


def indoor_scene(seed: int = 0) -> tuple[GaussianScene, Camera]:
    """synth.room_scene with a camera inside it looking across the room, and near-camera Gaussians:
    a cluster of 400 leaves 0.12–0.45 units in front of the lens at the lower left of the view,
    reaching beyond the frame (so the frame border cuts a surface, as in a real room), and
    30 floaters (σ 0.004, opacity 0.5) 0.05–0.3 units away, where a naive slicing fogs the frame."""
    room = room_scene()
    cam = look_at((0.5, -0.1, -2.2), (-0.2, 0.4, 2.5), 240, 180, 70.0)
    rng = np.random.default_rng(seed)
    parts = Parts.empty()
    depth = rng.uniform(0.12, 0.45, 400)
    px = np.stack([rng.uniform(-0.3, 0.35, 400) * 240, rng.uniform(0.6, 1.4, 400) * 180], 1)
    cam_pts = np.stack([(px[:, 0] - cam.cx) / cam.fx * depth, (px[:, 1] - cam.cy) / cam.fy * depth, depth], 1)
    world = (cam_pts - cam.T) @ cam.R
    parts.add(world, 0.012, np.array([0.2, 0.5, 0.15]) * rng.uniform(0.6, 1.2, (400, 1)), 0.9)
    d2 = rng.uniform(0.05, 0.3, 30)
    c2 = np.stack([rng.uniform(-0.6, 0.6, 30) * d2, rng.uniform(-0.45, 0.45, 30) * d2, d2], 1)
    parts.add((c2 - cam.T) @ cam.R, 0.004, rng.uniform(0.3, 0.9, (30, 3)), 0.5)
    return _merged(room, parts.build("srgb", "near"), "room inside"), cam


def near_wall_scene() -> tuple[GaussianScene, Camera, float]:
    """indoor_scene's room and camera with, instead of the near cluster, a wall of opaque grey
    Gaussians 0.6 units in front of the lens that fills the frame and reaches 40 % beyond each
    border, with an opening over the middle third of the view (a doorway onto the room). Returns
    the scene, the camera and the wall's camera depth (scene units)."""
    room = room_scene()
    cam = look_at((0.5, -0.1, -2.2), (-0.2, 0.4, 2.5), 240, 180, 70.0)
    depth, spacing = 0.6, 0.008
    half_w, half_h = 1.4 * cam.cx / cam.fx * depth, 1.4 * cam.cy / cam.fy * depth
    gx, gy = np.meshgrid(np.arange(-half_w, half_w, spacing), np.arange(-half_h, half_h, spacing))
    keep = ~((np.abs(gx) < half_w / 1.4 / 3) & (np.abs(gy) < half_h / 1.4 / 3))
    cam_pts = np.stack([gx[keep], gy[keep], np.full(keep.sum(), depth)], 1)
    rng = np.random.default_rng(1)
    parts = Parts.empty()
    parts.add((cam_pts - cam.T) @ cam.R, 0.6 * spacing,
              np.array([0.75, 0.72, 0.65]) * rng.uniform(0.9, 1.1, (len(cam_pts), 1)), 0.98)
    return _merged(room, parts.build("srgb", "wall"), "room behind a near wall"), cam, depth


def _merged(a: GaussianScene, b: GaussianScene, name: str) -> GaussianScene:
    return GaussianScene(*(np.concatenate([getattr(a, f), getattr(b, f)])
                           for f in ("means", "quats", "scales", "opacities", "sh_dc")),
                         colour_space="srgb", name=name)


PLACES = {"corridor": "corridor.compressed.ply", "kitchen_balcony": "kitchen_balcony.compressed.ply",
          "showroom": "showroom/lod-meta.json"}
"""The shared places (rooms seen from inside) by name, as files of the scenes folder; their views
are dofview.bench.places's (``corridor_1`` …)."""


def place_view_names() -> list[str]:
    """Every place view of dofview/bench/places: ``corridor_1``, ``corridor_2``, …"""
    return [f"{p}_{i + 1}" for p in PLACES for i in range(len(place_views(p)))]


def scene_cases(name: str, folder: Path, width: int, lod: int | None = None) -> tuple[GaussianScene, Camera, callable]:
    """The scene, camera and a function renderer → [(label, lens)] of one study scene: a file of
    ``folder``, a synthetic room ("indoor", "near_wall"), or a place view ("corridor_1": the view's
    camera at ``width``, focused on its subject, largest blur 8 and 16 px between the 20th and 95th
    depth percentiles, as indoors; ``lod``: the showroom's level)."""
    h = width * 3 // 4
    place, _, n = name.rpartition("_")
    if place in PLACES and n.isdigit():
        from dofview.io import load_scene

        scene = load_scene(folder / PLACES[place], progress=False, **({"lod": lod} if place == "showroom" else {}))
        view = place_views(place)[int(n) - 1]
        cam = view.camera.resized(width, round(width * view.camera.height / view.camera.width))

        def place_lenses(renderer: Renderer) -> list[tuple[str, Lens]]:
            fr = renderer.render(cam, Lens(view.focus, 0.0), pinhole_settings(RenderSettings()))
            near, far = depth_percentiles(fr, (20.0, 95.0))
            return [(f"blur{b:g}", Lens(view.focus, aperture_for_blur(b, view.focus, near, far))) for b in (8.0, 16.0)]

        return scene, cam, place_lenses
    if name in ("indoor", "near_wall"):
        scene, cam, *wall = indoor_scene() if name == "indoor" else near_wall_scene()
        cam = cam.resized(width, h)
    else:
        from dofview.io import load_scene

        scene = load_scene(folder / name, progress=False)
        cam = study_views(scene, 1, width, h)[0]
        wall = []

    def lenses(renderer: Renderer) -> list[tuple[str, Lens]]:
        if name == "near_wall":  # focus on the room, the wall 60 or 120 px of CoC (at 240 px wide)
            zf = depth_percentiles(renderer.render(cam, Lens(1.0, 0.0), pinhole_settings(RenderSettings())),
                                   (60.0,))[0]
            return [(f"wall{c:g}", Lens(zf, 2 * c * width / 240 / (1 / wall[0] - 1 / zf))) for c in (60.0, 120.0)]
        pcts = dict(focus_pct=70.0, span_pcts=(20.0, 95.0)) if name == "indoor" else {}
        return list(zip(("blur8", "blur16"), cases_for(renderer, cam, **pcts)))

    return scene, cam, lenses


# ---- quality ----------------------------------------------------------------------------------------
def quality_case(renderer: Renderer, camera: Camera, lens: Lens, samples: int, rules: list[SliceRule],
                 tm: Tonemap = Tonemap()) -> tuple[dict[str, dict], dict[str, Frame]]:
    """PSNR/SSIM (and layer counts) of the anchors and the sliced mode with each rule for one case,
    and the frames ("truth", each method) for a figure."""
    truth = make_references(renderer, camera, lens, RenderSettings(), samples, False, lambda: None).physical
    out, frames = {}, {"truth": truth}
    for name, k in ANCHOR_KS.items():
        frames[name] = renderer.render(camera, lens, replace(ANCHOR, k=k))
        out[name] = errors(frames[name], truth, tm, False)
    for rule in rules:
        name = rule_name(rule)
        frames[name] = sliced_render(renderer, camera, lens, rule)
        out[name] = {**errors(frames[name], truth, tm, False), "layers": len(renderer.sliced_layers)}
    return out, frames


def figure(path: Path, frames: dict[str, Frame], res: dict[str, dict], title: str, tm: Tonemap = Tonemap()) -> None:
    """Write a PNG of truth | best anchor | the default sliced mode, each labelled with its PSNR."""
    from PIL import Image, ImageDraw

    best = max(ANCHOR_KS, key=lambda k: res[k]["psnr"])
    panels = []
    for key, label in (("truth", "thin lens (truth)"), (best, f"best anchor {best}: {res[best]['psnr']:.2f} dB"),
                       ("sliced", f"sliced: {res['sliced']['psnr']:.2f} dB")):
        f = frames[key]
        img = Image.fromarray((np.clip(display(f.rgba, f.encoded, tm), 0, 1) * 255 + 0.5).astype(np.uint8))
        ImageDraw.Draw(img).text((4, 4), label, fill=(255, 255, 255))
        panels.append(img)
    w, h = panels[0].size
    sheet = Image.new("RGB", (3 * w, h + 16), (0, 0, 0))
    for i, p in enumerate(panels):
        sheet.paste(p, (i * w, 16))
    ImageDraw.Draw(sheet).text((4, 2), title, fill=(255, 255, 255))
    path.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(path)


def quality(args: argparse.Namespace) -> int:
    rules = [SLICE_RULE] + [parse_rule(r) for r in args.rule or []]
    names = args.only or [*SCENES, *place_view_names(), "indoor", "near_wall"]
    rows = []
    for name in names:
        scene, cam, lenses = scene_cases(name, args.scenes, args.width, args.lod)
        renderer = get_backend(args.raster, scene)
        t0 = time.perf_counter()
        try:
            cases = lenses(renderer)
            for label, lens in cases:
                res, frames = quality_case(renderer, cam, lens, args.samples, rules)
                best = max(v["psnr"] for k, v in res.items() if k in ANCHOR_KS)
                best_ssim = max(v["ssim"] for k, v in res.items() if k in ANCHOR_KS)
                for method, v in res.items():
                    print(f"{name}\t{label}\t{method}\t{v['psnr']:.2f}\t{v['psnr'] - best:+.2f}\t{v['ssim']:.4f}\t"
                          f"{v['ssim'] - best_ssim:+.4f}\t{v.get('layers', '')}", flush=True)
                    rows.append((name, label, method, v["psnr"], v["psnr"] - best, v["ssim"], v["ssim"] - best_ssim,
                                 v.get("layers", "")))
                if args.figure and name == names[0] and label == cases[-1][0]:
                    figure(args.figure, frames, res, f"{name}, {label}, {cam.width}x{cam.height}")
        finally:
            renderer.release()
        print(f"# {name}: {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
    if args.markdown:
        lines = ["| scene | case | method | PSNR dB | vs best anchor dB | SSIM | vs best anchor | layers |",
                 "|---|---|---|---|---|---|---|---|"]
        lines += [f"| {n} | {c} | {m} | {p:.2f} | {d:+.2f} | {s:.4f} | {ds:+.4f} | {k} |" for n, c, m, p, d, s, ds, k in rows]
        args.markdown.write_text("\n".join(lines) + "\n")
    return 0


# ---- timing -----------------------------------------------------------------------------------------
def timing_views(args: argparse.Namespace):
    """(scene, camera, place lenses or None) of each of ``args.scenes`` (timing, passes): a file at
    its study view, or with ``--places`` a place view at its own camera."""
    from dofview.io import load_scene

    for path in args.scenes:
        if args.places is not None and str(path) in place_view_names():
            yield scene_cases(str(path), args.places, args.width, args.lod)
        else:
            scene = load_scene(path, progress=False)
            yield scene, study_views(scene, 1, args.width, args.height)[0], None


def timing_lenses(renderer: Renderer, camera: Camera, place_lenses) -> tuple[Lens, Lens]:
    """The timed cases' lenses: A = 100 px·unit and the largest blur in view 16 px (a place view's
    own), both focused as the latter."""
    blur16 = place_lenses(renderer)[-1][1] if place_lenses else cases_for(renderer, camera, blurs=(16.0,))[0]
    return Lens(blur16.focus, 100.0), blur16


def timing(args: argparse.Namespace) -> int:
    rules = [SLICE_RULE] + [parse_rule(r) for r in args.rule or []]
    print("scene\tbackend\tcase\tlayers\tsplat/pinhole\t" + "\t".join(f"{rule_name(r)}/pinhole" for r in rules)
          + "\tpinhole ms\tsliced MB/Mpx")
    for scene, cam, place_lenses in timing_views(args):
        for backend in ("quad", "compute"):
            r = get_backend(backend, scene)
            try:
                for label, lens in zip(("A=100", "blur16"), timing_lenses(r, cam, place_lenses)):
                    modes = {"pinhole": (Lens(lens.focus, 0.0), PINHOLE, None), "splat": (lens, PINHOLE, None),
                             **{i: (lens, SLICED, rule) for i, rule in enumerate(rules)}}
                    times: dict[object, list[float]] = {m: [] for m in modes}
                    layers = 0
                    for rep in range(args.reps + 1):
                        for m, (ln, st, rule) in modes.items():
                            r.slice_rule = rule
                            if len(rules) > 1:  # rules of other guard bands size the targets anew
                                r.draw(cam, ln, st)
                            r.ctx.finish()
                            t0 = time.perf_counter()
                            r.draw(cam, ln, st)
                            r.ctx.finish()
                            if rep:  # the first round compiles and allocates
                                times[m].append(time.perf_counter() - t0)
                            if m == 0:
                                layers = len(r.sliced_layers)
                    r.slice_rule = None
                    r.draw(cam, lens, SLICED)
                    med = {m: float(np.median(v)) for m, v in times.items()}
                    mb = r.sliced_bytes / (cam.width * cam.height)  # the default's targets, per pixel of frame
                    print(f"{scene.name}\t{backend}\t{label}\t{layers}\t{med['splat'] / med['pinhole']:.2f}\t"
                          + "\t".join(f"{med[i] / med['pinhole']:.2f}" for i in range(len(rules)))
                          + f"\t{med['pinhole'] * 1e3:.0f}\t{mb:.0f}", flush=True)
            finally:
                r.release()
    return 0


# ---- where the sliced frame's time goes ---------------------------------------------------------
PASS_KINDS = ("plan", "clear", "prepare splats", "blend", "list tiles", "visible", "visible + prepare", "reduce",
              "prepare", "empty", "occupancy", "gather", "sprites", "upsample", "resolve", "other")
"""The kinds of pass a sliced frame's profile names (rendering/sliced.py), in the order drawn."""


def passes(args: argparse.Namespace) -> int:
    rows = []  # (label, pinhole ms, sliced ms, {kind: ms})
    print("scene\tbackend\tcase\tlayers\tpinhole ms\tsliced ms\tsliced/pinhole\tprofiled ms\t"
          + "\t".join(PASS_KINDS))
    for path, (scene, cam, place_lenses) in zip(args.scenes, timing_views(args)):
        for backend in args.raster or ("quad", "compute"):
            r = get_backend(backend, scene)
            try:
                for label, lens in zip(("A=100", "16 px"), timing_lenses(r, cam, place_lenses)):
                    pinhole = (Lens(lens.focus, 0.0), PINHOLE)
                    r.draw(cam, lens, SLICED)  # compiles and allocates
                    r.draw(cam, *pinhole)
                    frame = {"pinhole": [], "sliced": []}
                    kinds: dict[str, list[float]] = {k: [] for k in PASS_KINDS}
                    for _ in range(args.reps):
                        for mode, (ln, st) in (("pinhole", pinhole), ("sliced", (lens, SLICED))):
                            r.ctx.finish()
                            t0 = time.perf_counter()
                            r.draw(cam, ln, st)
                            r.ctx.finish()
                            frame[mode].append((time.perf_counter() - t0) * 1e3)
                        laps = r.sliced_pass_times(cam, lens, SLICED)
                        for k in PASS_KINDS:
                            kinds[k].append(laps.get(k, 0.0))
                    med = {k: float(np.median(v)) for k, v in kinds.items()}
                    ph, sl = float(np.median(frame["pinhole"])), float(np.median(frame["sliced"]))
                    name = Path(str(path)).name
                    name = Path(str(path)).parent.name if name == "lod-meta.json" else name  # a LOD set: its folder
                    rows.append((f"{name} {backend} {label}", ph, sl, med))
                    print(f"{name}\t{backend}\t{label}\t{len(r.sliced_layers)}\t{ph:.0f}\t{sl:.0f}\t{sl / ph:.2f}\t"
                          f"{sum(med.values()):.0f}\t" + "\t".join(f"{med[k]:.1f}" for k in PASS_KINDS), flush=True)
            finally:
                r.release()
    if args.figure is not None:
        size = f"{args.width}×{args.height}" + (f", places {args.width}×{args.width * 3 // 4}" if args.places else "")
        pass_figure(args.figure, rows, size)
    return 0


def pass_figure(path: Path, rows: list[tuple[str, float, float, dict[str, float]]], size: str) -> None:
    """Write a PNG: per row the sliced frame's passes as stacked bars in units of the pinhole frame,
    with the frame drawn without the waits marked, and the targets 1.2× and 1.5×."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(12, 0.42 * len(rows) + 1.6))
    colours = plt.get_cmap("tab20").colors
    y = np.arange(len(rows))[::-1]
    for i, kind in enumerate(PASS_KINDS):
        left = np.array([sum(m[k] for k in PASS_KINDS[:i]) / ph for _, ph, _, m in rows])
        width = np.array([m[kind] / ph for _, ph, _, m in rows])
        if width.any():
            ax.barh(y, width, left=left, color=colours[i % len(colours)], label=kind, height=0.7)
    ax.scatter([sl / ph for _, ph, sl, _ in rows], y, marker="|", s=300, color="black", zorder=3,
               label="sliced frame drawn without waits")
    for x, style in ((1.0, "-"), (1.2, "--"), (1.5, ":")):
        ax.axvline(x, color="grey", linestyle=style, linewidth=1)
    ax.set_yticks(y, [label for label, *_ in rows])
    ax.set_xlabel(f"time in units of the pinhole frame ({size}; lines at 1, 1.2 and 1.5)")
    ax.set_title("Where the sliced frame's time goes (each kind of pass timed between GL waits)")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m dofview.bench.sliced_study", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="what", required=True)
    q = sub.add_parser("quality")
    q.add_argument("--scenes", type=Path, required=True,
                   help="folder of the five real scenes (../shared/scenes; tests/data holds stand-ins for two)")
    q.add_argument("--width", type=int, default=240)
    q.add_argument("--samples", type=int, default=64)
    q.add_argument("--only", action="append",
                   help="scene file name, place view (corridor_1, …), 'indoor' or 'near_wall'; repeatable")
    q.add_argument("--lod", type=int, default=1, help="the showroom's level (0: 1.5M Gaussians, 1: 747k)")
    q.add_argument("--raster", default="quad")
    q.add_argument("--rule", action="append", help="a slicing beside the default: KEY=V[,KEY=V] of SliceRule; repeatable")
    q.add_argument("--markdown", type=Path, help="also write the figures as a markdown table to this file")
    q.add_argument("--figure", type=Path, help="PNG of truth | best anchor | sliced (first scene, last case)")
    t = sub.add_parser("timing")
    t.add_argument("scenes", type=Path, nargs="+")
    t.add_argument("--width", type=int, default=640)
    t.add_argument("--height", type=int, default=360)
    t.add_argument("--reps", type=int, default=3)
    t.add_argument("--rule", action="append", help="a slicing beside the default: KEY=V[,KEY=V] of SliceRule; repeatable")
    t.add_argument("--places", type=Path, help="folder of the shared places: SCENE may then name a place view")
    t.add_argument("--lod", type=int, default=1, help="the showroom's level (0: 1.5M Gaussians, 1: 747k)")
    p = sub.add_parser("passes")
    p.add_argument("scenes", type=Path, nargs="+")
    p.add_argument("--width", type=int, default=640)
    p.add_argument("--height", type=int, default=360)
    p.add_argument("--reps", type=int, default=3)
    p.add_argument("--places", type=Path, help="folder of the shared places: SCENE may then name a place view")
    p.add_argument("--lod", type=int, default=1, help="the showroom's level (0: 1.5M Gaussians, 1: 747k)")
    p.add_argument("--raster", action="append", choices=("quad", "compute"), help="a backend (default: both); repeatable")
    p.add_argument("--figure", type=Path, help="PNG of the passes as stacked bars, in units of the pinhole frame")
    args = ap.parse_args(argv)
    return {"quality": quality, "timing": timing, "passes": passes}[args.what](args)


if __name__ == "__main__":
    sys.exit(main())
