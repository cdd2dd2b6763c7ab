"""Sliced depth of field against the physical thin lens: a prototype driver on today's renderer.

Each slice of :mod:`dofview.rendering.slices` is blended by the GL renderer itself, unchanged: the
slice's Gaussians become a sub-scene (GaussianScene.subset) rendered as a pinhole with the same
camera, read back, then blurred and composited in numpy. Slower than a GL slice path, but exactly
what one computes. Scored like ``bench --views`` (study.py): PSNR/SSIM of the display images
against the linear-light average of pinhole images over the lens disk, next to the best anchor.

    python -m dofview.bench.sliced_study --scenes DIR [--width 240] [--samples 64] [--only NAME]
        [--markdown TABLE.md] [--figure PNG]

prints one tab-separated line per scene, case (largest blur in view 8 or 16 px; for the near
wall, the wall's CoC 60 or 120 px) and method: PSNR, PSNR over the best anchor, SSIM, SSIM over
the best anchor; --markdown writes the same as a table, --figure truth | best anchor | chosen
rule of the first scene's second case.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from dofview.bench.primitives import Parts, dc_from_colour
from dofview.bench.study import ANCHOR_KS, depth_percentiles, study_views
from dofview.bench.synth import room_scene
from dofview.bench.variants import errors, make_references, pinhole_settings
from dofview.camera import Camera, look_at
from dofview.frame import Frame, RenderSettings
from dofview.lens import Lens, aperture_for_blur
from dofview.rendering import Renderer, get_backend
from dofview.rendering.slices import (SliceRule, Slicing, assign_slices, share_weights, signed_coc, sliced_image,
                                     to_blend_space)
from dofview.rendering.depth_order import camera_depths
from dofview.scene import GaussianScene
from dofview.tonemap import Tonemap
from dofview.tonemap.display import display

SCENES = ("two_planes.ply", "burger.ply", "guitar.compressed.ply", "biker.spz", "tap.spz")
ANCHOR = RenderSettings(tau=1 / 255, k=1 / 4, opacity_norm="energy", cut="drop")


@dataclass
class SliceFrames:
    """The slices of one camera and lens as the renderer blends them: ``layers`` (H, W, 4) linear
    premultiplied RGBA front to back, each with its blur radius px (0: drawn blurred already), the
    signed CoC px of its middle (±inf: the per-splat front and back layers) and its neighbour
    share (None: not shared)."""

    layers: list[np.ndarray]
    radii: list[float]
    centres: list[float]
    splits: list[tuple[np.ndarray, float] | None]
    slicing: Slicing
    encoded: bool

    def add(self, rgba: np.ndarray, radius: float, centre: float, split: tuple[np.ndarray, float] | None) -> None:
        """Append one layer behind the others (split: slices.sliced_image's)."""
        self.layers.append(rgba)
        self.radii.append(radius)
        self.centres.append(centre)
        self.splits.append(split)


def render_slices(renderer: Renderer, camera: Camera, lens: Lens, rule: SliceRule,
                  per_splat: RenderSettings | None = RenderSettings(), share: bool = True) -> SliceFrames:
    """Blend each slice of ``renderer``'s scene for ``rule`` with today's renderer (a sub-scene per
    non-empty slice, same backend and context, pinhole at τ = 0 as the truth's passes); the splats
    beyond ``rule.huge`` are drawn with the real lens and ``per_splat`` settings as a front and a
    back layer (None: left out, as a lens far wider than their distance nearly hides them).

    ``share``: neighbour sharing (slices.share_weights): the layers are the depth ranges between
    consecutive slice centres, each blurred partly by either centre's radius; the split τ per
    pixel is the blend of the splats' shares t, drawn as a second pass with t as a grey colour
    (a GL path would write it to a fifth channel). False: disjoint slices, one radius each."""
    scene = renderer.scene
    z = camera_depths(scene.means, camera)
    live = np.nonzero(z > RenderSettings().near)[0]
    c = signed_coc(z[live], lens)
    slicing = assign_slices(c, rule)
    mids = 0.5 * (slicing.edges[:-1] + slicing.edges[1:])
    inside = (slicing.index >= 0) & (slicing.index < slicing.count)
    pin, pin_st = Lens(lens.focus, 0.0), pinhole_settings(RenderSettings())
    out = SliceFrames([], [], [], [], slicing, scene.colour_space == "srgb")

    def draw(members: np.ndarray, lens_: Lens, st: RenderSettings, grey: np.ndarray | None = None) -> np.ndarray:
        sub_scene = scene.subset(members)
        if grey is not None:
            sub_scene = replace(sub_scene, sh_dc=np.repeat(dc_from_colour(grey)[:, None], 3, 1).astype(np.float32),
                                sh_rest=None)
        sub = get_backend(renderer.name, sub_scene, ctx=renderer.ctx)
        try:
            return sub.render(camera, lens_, st).rgba
        finally:
            sub.release()

    def huge_layer(own: np.ndarray, centre: float) -> None:
        if own.any() and per_splat is not None:
            out.add(draw(live[own], lens, per_splat), 0.0, centre, None)

    huge_layer(slicing.index == -1, math.inf)
    if share:
        interval, t = share_weights(c, mids)
        for j in range(slicing.count + 1):
            own = inside & (interval == j)
            if not own.any():
                continue
            rgba = draw(live[own], pin, pin_st)
            front, back = max(j - 1, 0), min(j, slicing.count - 1)
            split = None
            if front != back:
                weight = to_blend_space(draw(live[own], pin, pin_st, t[own]), out.encoded)[..., 0]
                alpha = rgba[..., 3]
                split = (np.where(alpha > 0, np.clip(weight / np.maximum(alpha, 1e-12), 0, 1), 0.0),
                         float(slicing.radius[back]))
            out.add(rgba, float(slicing.radius[front]), float(0.5 * (mids[front] + mids[back])), split)
    else:
        for s in range(slicing.count):
            own = slicing.index == s
            if own.any():
                out.add(draw(live[own], pin, pin_st), float(slicing.radius[s]), float(mids[s]), None)
    huge_layer(slicing.index == slicing.count, -math.inf)
    return out


def sliced_frame(sf: SliceFrames, **blur) -> Frame:
    """The composite of ``sf`` (keywords: slices.sliced_image's) as a Frame (no depth image)."""
    h, w = sf.layers[0].shape[:2]
    rgba = sliced_image(sf.layers, sf.radii, sf.encoded, centres=sf.centres, splits=sf.splits, **blur)
    return Frame(rgba=rgba, depth=np.zeros((h, w), np.float32), encoded=sf.encoded)


# ---- the cases --------------------------------------------------------------------------------------
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
    extra = parts.build("srgb", "near")
    merged = GaussianScene(*(np.concatenate([getattr(room, a), getattr(extra, a)])
                             for a in ("means", "quats", "scales", "opacities", "sh_dc")),
                           colour_space="srgb", name="room inside")
    return merged, cam


def cases_for(renderer: Renderer, camera: Camera, blurs=(8.0, 16.0), focus_pct: float = 50.0,
              span_pcts: tuple[float, float] = (5.0, 95.0)) -> list[Lens]:
    """Lenses focused at the ``focus_pct`` depth percentile of the pinhole image whose largest blur
    between the ``span_pcts`` depth percentiles is each of ``blurs`` px (lens.aperture_for_blur).
    Indoors the near-camera Gaussians lie below the span and get far more blur."""
    fr = renderer.render(camera, Lens(1.0, 0.0), pinhole_settings(RenderSettings()))
    near, far, zf = depth_percentiles(fr, (*span_pcts, focus_pct))
    return [Lens(zf, aperture_for_blur(b, zf, near, far)) for b in blurs]


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
    parts.add((cam_pts - cam.T) @ cam.R, 0.6 * spacing, np.array([0.75, 0.72, 0.65]) * rng.uniform(0.9, 1.1, (len(cam_pts), 1)),
              0.98)
    wall = parts.build("srgb", "wall")
    merged = GaussianScene(*(np.concatenate([getattr(room, a), getattr(wall, a)])
                             for a in ("means", "quats", "scales", "opacities", "sh_dc")),
                           colour_space="srgb", name="room behind a near wall")
    return merged, cam, depth


DEFAULT_RULE = SliceRule()
COMPOSITE_VARIANTS = {
    "disjoint over": (False, {}),
    "disjoint hybrid": (False, {"mode": "hybrid"}),
    "shared over": (True, {}),
    "shared window 2": (True, {"window": 2.0}),
    "shared window 4": (True, {"window": 4.0}),
    "shared hybrid": (True, {"mode": "hybrid"}),
}
"""Sliced variants: (neighbour sharing, slices.sliced_image keywords); every blur above 8 px at
reduced resolution (as the chosen rule)."""
DEFAULT_COMPOSITE = "shared hybrid"
"""The chosen rule: neighbour sharing, hybrid composite (seamless on a slanted floor, the best
figures of the seamless variants; see the module docstring's table command)."""
HUGE_VARIANTS = {"huge 80 per-splat": (80.0, RenderSettings()), "huge 80 dropped": (80.0, None),
                 "drop |c| > W/2": (120.0, None), "no huge cut": (math.inf, RenderSettings())}
"""Indoors, how the splats beyond the huge-CoC threshold (px at 240 px wide, scaled with the frame
width) are drawn, each with the composites "disjoint over" and DEFAULT_COMPOSITE. Dropping
|c| > W/2: a splat whose blur disk is wider than the frame spreads its light mostly outside it,
and the replicate guard would extrapolate it over the whole disk."""


def study_case(renderer: Renderer, camera: Camera, lens: Lens, samples: int, indoor: bool,
               tm: Tonemap = Tonemap()) -> tuple[dict[str, dict], dict[str, Frame]]:
    """PSNR/SSIM (and slice counts) of the anchors and the sliced variants for one case, and the
    frames ("truth", each anchor, each variant) for a figure."""
    truth = make_references(renderer, camera, lens, RenderSettings(), samples, False, lambda: None).physical
    out, frames = {}, {"truth": truth}
    for name, k in ANCHOR_KS.items():
        frames[name] = renderer.render(camera, lens, replace(ANCHOR, k=k))
        out[name] = errors(frames[name], truth, tm, False)
    huge = HUGE_VARIANTS if indoor else {"": (DEFAULT_RULE.huge, RenderSettings())}
    composites = ({k: COMPOSITE_VARIANTS[k] for k in ("disjoint over", DEFAULT_COMPOSITE)} if indoor
                  else COMPOSITE_VARIANTS)
    for hname, (threshold, per_splat) in huge.items():
        rule = replace(DEFAULT_RULE, huge=threshold * camera.width / 240)
        for share in (False, True):
            t0 = time.perf_counter()
            sf = render_slices(renderer, camera, lens, rule, per_splat, share)
            render_s = time.perf_counter() - t0
            for cname, (c_share, kw) in composites.items():
                if c_share != share:
                    continue
                t0 = time.perf_counter()
                name = f"{hname}, {cname}" if hname else cname
                frames[name] = sliced_frame(sf, max_full_radius=8.0, **kw)
                e = errors(frames[name], truth, tm, False)
                e.update(slices=len(sf.layers), render_s=render_s, blur_s=time.perf_counter() - t0)
                out[name] = e
    return out, frames


def figure(path: Path, frames: dict[str, Frame], res: dict[str, dict], sliced: str, title: str,
           tm: Tonemap = Tonemap()) -> None:
    """Write a PNG of truth | best anchor | ``sliced``, each labelled with its PSNR."""
    from PIL import Image, ImageDraw

    best = max(ANCHOR_KS, key=lambda k: res[k]["psnr"])
    panels = []
    for key, label in (("truth", "thin lens (truth)"), (best, f"best anchor {best}: {res[best]['psnr']:.2f} dB"),
                       (sliced, f"sliced ({sliced}): {res[sliced]['psnr']:.2f} dB")):
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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m dofview.bench.sliced_study", description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", type=Path, required=True,
                    help="folder of the five real scenes (../shared/scenes; tests/data holds stand-ins for two)")
    ap.add_argument("--width", type=int, default=240)
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--only", action="append", help="scene file name, 'indoor' or 'near_wall'; repeatable")
    ap.add_argument("--raster", default="quad")
    ap.add_argument("--markdown", type=Path, help="also write the figures as a markdown table to this file")
    ap.add_argument("--figure", type=Path, help="PNG of truth | best anchor | default sliced (first scene, 16 px)")
    args = ap.parse_args(argv)
    from dofview.io import load_scene

    names = args.only or [*SCENES, "indoor", "near_wall"]
    h = args.width * 3 // 4
    rows = []
    for name in names:
        if name in ("indoor", "near_wall"):
            scene, cam, *wall = indoor_scene() if name == "indoor" else near_wall_scene()
            cam = cam.resized(args.width, h)
        else:
            scene = load_scene(args.scenes / name, progress=False)
            cam = study_views(scene, 1, args.width, h)[0]
        renderer = get_backend(args.raster, scene)
        t0 = time.perf_counter()
        try:
            if name == "near_wall":  # focus on the room, the wall 60 or 120 px of CoC (at 240 px wide)
                zf = depth_percentiles(renderer.render(cam, Lens(1.0, 0.0), pinhole_settings(RenderSettings())),
                                       (60.0,))[0]
                lenses = [Lens(zf, 2 * c * args.width / 240 / (1 / wall[0] - 1 / zf)) for c in (60.0, 120.0)]
                labels = ("wall60", "wall120")
            else:
                pcts = dict(focus_pct=70.0, span_pcts=(20.0, 95.0)) if name == "indoor" else {}
                lenses, labels = cases_for(renderer, cam, **pcts), ("blur8", "blur16")
            for label, lens in zip(labels, lenses):
                res, frames = study_case(renderer, cam, lens, args.samples, name in ("indoor", "near_wall"))
                best = max(v["psnr"] for k, v in res.items() if k in ANCHOR_KS)
                best_ssim = max(v["ssim"] for k, v in res.items() if k in ANCHOR_KS)
                for method, v in res.items():
                    extra = (f" slices {v['slices']} render {v['render_s']:.1f}s blur {v['blur_s']:.2f}s"
                             if "slices" in v else "")
                    print(f"{name}\t{label}\t{method}\t{v['psnr']:.2f}\t{v['psnr'] - best:+.2f}\t"
                          f"{v['ssim']:.4f}\t{v['ssim'] - best_ssim:+.4f}{extra}", flush=True)
                    rows.append((name, label, method, v["psnr"], v["psnr"] - best, v["ssim"], v.get("slices", "")))
                if args.figure and name == names[0] and label == labels[-1]:
                    default = (f"huge 80 per-splat, {DEFAULT_COMPOSITE}" if name in ("indoor", "near_wall")
                               else DEFAULT_COMPOSITE)
                    figure(args.figure, frames, res, default, f"{name}, {label}, {args.width}x{h}")
        finally:
            renderer.release()
        print(f"# {name}: {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
    if args.markdown:
        lines = ["| scene | case | method | PSNR dB | vs best anchor dB | SSIM | layers |", "|---|---|---|---|---|---|---|"]
        lines += [f"| {n} | {c} | {m} | {p:.2f} | {d:+.2f} | {s:.4f} | {k} |" for n, c, m, p, d, s, k in rows]
        args.markdown.write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
