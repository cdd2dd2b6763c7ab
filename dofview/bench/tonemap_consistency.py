"""Tone-mapping consistency along a camera path (seed 004, §6: temporal consistency).

For each adaptive operator, with per-frame and with smoothed statistics, an orbit of ``--frames``
views is rendered and each frame is shown twice: with the statistics it was shown with, and with
the previous frame's. Their difference at a pixel is what the tone curve's change alone did to
it — the displayed change beyond what the pixel's radiance changed. It is averaged over the
pixels of frame i + 1 that see the same surface as a pixel of frame i (reprojected through the
depth buffer with the two cameras: a static-scene correspondence), in 8-bit display levels, and
reported with the mean displayed change of those pixel pairs for scale, plus clipped/crushed shares.

Scenes: samples/lamp.ply (linear HDR) and an HDR version of a real sRGB capture
(:func:`hdr_variant`: its colours linearised, a few places turned into lights 50–500× its diffuse
white). Run ``python -m dofview.bench.tonemap_consistency`` (``--help``); it prints a Markdown
table and writes a plot (default docs/images/tonemap_consistency.png); ``--fidelity`` prints the
trained-look and clipping figures of issue 20 instead.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from dofview.camera import Camera, look_at
from dofview.errors import DofviewError
from dofview.scene import SH_C0, GaussianScene
from dofview.tonemap import OPERATORS, StatsSmoother, Tonemap, display
from dofview.tonemap.stats import SMOOTHING_T0_S, clipped_crushed, frame_stats

ROOT = Path(__file__).resolve().parents[2]
LIGHT_GAINS = (50.0, 150.0, 300.0, 500.0)  # × diffuse white, one per light
DEPTH_MATCH = 0.02  # relative depth difference under which two reprojected pixels see one surface


def hdr_variant(scene: GaussianScene, lights: int = 4, share: float = 0.002, seed: int = 0) -> GaussianScene:
    """A linear HDR scene from an sRGB-trained one: colours decoded to linear light (diffuse white
    1; view dependence dropped, the SH rest is display-encoded), and ``lights`` places — the
    ``share`` of Gaussians nearest a random opaque Gaussian each — set to LIGHT_GAINS × white in
    their own hue."""
    rng = np.random.default_rng(seed)
    linear = np.power(scene.base_colour().astype(np.float64), 2.2)
    opaque = np.flatnonzero(scene.opacities > 0.5)
    if len(opaque) < lights:
        raise DofviewError(f"{scene.name}: fewer than {lights} opaque Gaussians to make lights of")
    per_light = max(1, round(share * scene.count))
    for gain, centre in zip(LIGHT_GAINS * (lights // len(LIGHT_GAINS) + 1), rng.choice(opaque, lights, replace=False)):
        near = np.argsort(np.linalg.norm(scene.means - scene.means[centre], axis=1))[:per_light]
        hue = linear[near] / np.maximum(linear[near].max(axis=1, keepdims=True), 1e-6)
        linear[near] = gain * np.maximum(hue, 0.05)
    return replace(scene, sh_dc=((linear - 0.5) / SH_C0).astype(np.float32), sh_rest=None, colour_space="linear",
                   name=f"{scene.name}-hdr")


def orbit(centre: np.ndarray, eye: np.ndarray, frames: int, degrees: float, width: int, height: int,
          fov: float = 50.0) -> list[Camera]:
    """``frames`` cameras turning ``degrees`` about the world −y axis through ``centre``, from
    ``eye``, all looking at ``centre``."""
    off = np.asarray(eye, np.float64) - centre
    cams = []
    for a in np.radians(np.linspace(0.0, degrees, frames)):
        c, s = math.cos(a), math.sin(a)
        rot = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
        cams.append(look_at(centre + rot @ off, centre, width, height, fov))
    return cams


def correspondence(cam_a: Camera, depth_a: np.ndarray, cam_b: Camera, depth_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels of frame b that see the surface a pixel of frame a saw: ((M,) flat indices into b,
    (M,) into a). Each covered pixel of a is lifted to 3-D by its depth, projected into b and kept
    where b's depth agrees within DEPTH_MATCH (not occluded, same surface)."""
    h, w = depth_a.shape
    ys, xs = np.nonzero(depth_a > 0)
    z = depth_a[ys, xs].astype(np.float64)
    rays = np.stack([(xs + 0.5 - cam_a.cx) / cam_a.fx, (ys + 0.5 - cam_a.cy) / cam_a.fy, np.ones_like(z)], 1) * z[:, None]
    world = (rays - cam_a.T) @ cam_a.R  # camera → world: R^T (p − T)
    zb = cam_b.world_to_camera(world)[:, 2]
    uv = cam_b.project(world)
    xb, yb = np.floor(uv[:, 0]).astype(np.int64), np.floor(uv[:, 1]).astype(np.int64)
    inside = (xb >= 0) & (xb < w) & (yb >= 0) & (yb < h) & (zb > 0)
    xb, yb, zb, src = xb[inside], yb[inside], zb[inside], (ys * w + xs)[inside]
    seen = depth_b[yb, xb]
    same = (seen > 0) & (np.abs(seen - zb) <= DEPTH_MATCH * zb)
    return (yb * w + xb)[same], src[same]


def measure(renderer, cameras: list[Camera], operator, t0: float | None, fps: float) -> dict[str, object]:
    """One operator along ``cameras``: ``t0`` None = per-frame statistics, else smoothed with that
    time constant at ``fps``. Returns per-step curve-change and displayed-change means (8-bit
    levels) and the orbit's worst clipped/crushed shares."""
    from dofview.lens import Lens
    from dofview.tonemap import to_uint8

    display_referred = renderer.scene.colour_space == "srgb"
    smoother = StatsSmoother(t0=t0) if t0 else None
    tm = Tonemap(operator=operator)
    prev = None
    curve, shown, clipped, crushed = [], [], [], []
    for cam in cameras:
        frame = renderer.render(cam, Lens(1.0, 0.0))
        stats = frame_stats(frame.rgba, operator, display_referred)
        if smoother is not None:
            stats = smoother.update(stats, 1.0 / fps)
        image = display(frame.rgba, frame.encoded, tm, stats, frame.depth)
        c, k = clipped_crushed(to_uint8(image), frame.alpha)
        clipped.append(c)
        crushed.append(k)
        if prev is not None:
            p_cam, p_frame, p_stats, p_image = prev
            idx_b, idx_a = correspondence(p_cam, p_frame.depth, cam, frame.depth)
            if len(idx_b):
                with_prev = display(frame.rgba, frame.encoded, tm, p_stats, frame.depth).reshape(-1, 3)
                now = image.reshape(-1, 3)
                curve.append(255.0 * float(np.abs(now[idx_b] - with_prev[idx_b]).mean()))
                shown.append(255.0 * float(np.abs(now[idx_b] - p_image.reshape(-1, 3)[idx_a]).mean()))
        prev = (cam, frame, stats, image)
    return {"curve": curve, "shown": shown, "clipped": max(clipped), "crushed": max(crushed)}


def object_orbit(scene: GaussianScene, frames: int, degrees: float, width: int, height: int) -> list[Camera]:
    """An orbit about a captured object's robust box centre, from 2.2× its half-diagonal, 19°
    above its horizon (world up −y)."""
    from dofview.framing import robust_box

    lo, hi = robust_box(scene)
    centre, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2
    eye = centre + 2.2 * radius * np.array([0.0, -0.35, -1.0]) / np.linalg.norm([0.0, -0.35, -1.0])
    return orbit(centre, eye, frames, degrees, width, height)


def scenes(width: int, height: int, frames: int, degrees: float):
    """(name, renderer, cameras) of the two benchmark scenes."""
    from dofview.io import load_scene
    from dofview.io.cameras import load_cameras_json
    from dofview.rendering import get_backend

    lamp = load_scene(ROOT / "samples" / "lamp.ply", progress=False)
    start = load_cameras_json(ROOT / "samples" / "lamp_cameras.json")[0]
    yield "lamp.ply", get_backend("quad", lamp), orbit(start.centre + 3.0 * start.forward, start.centre, frames, degrees, width, height)
    biker = hdr_variant(load_scene(ROOT / "tests" / "data" / "biker.spz", progress=False))
    yield "biker-hdr", get_backend("quad", biker), object_orbit(biker, frames, degrees, width, height)


SRGB_SCENES = ("tests/data/biker.spz", "tests/data/burger.ply", "tests/data/guitar.compressed.ply", "tests/data/tap.spz",
               "tests/data/two_planes.ply", "samples/cards.ply")


def fidelity(width: int, height: int) -> None:
    """Print, at 0 EV on the GPU display pass, each adaptive operator against the trained look
    (clip) on the sRGB scenes — PSNR and mean display luminance ratio — and its clipped/crushed
    shares on the two HDR scenes (first view of each orbit)."""
    from dofview.bench.metrics import psnr
    from dofview.io import load_scene
    from dofview.lens import Lens
    from dofview.rendering import get_backend
    from dofview.tonemap.operator import luminance

    adaptive = [n for n, c in OPERATORS.items() if c.adaptive]
    print("| sRGB scene | " + " | ".join(f"{n}: dB vs clip, mean ×" for n in adaptive) + " |")
    print("|---|" + "---|" * len(adaptive))
    for path in SRGB_SCENES:
        scene = load_scene(ROOT / path, progress=False)
        r = get_backend("quad", scene)
        frame = r.render(object_orbit(scene, 1, 0.0, width, height)[0], Lens(1.0, 0.0))
        mask = frame.alpha > 0.5
        trained = r.display_image(Tonemap()) / 255.0
        cells = []
        for name in adaptive:
            img = r.display_image(Tonemap(operator=OPERATORS[name]())) / 255.0
            ratio = luminance(img ** 2.2)[mask].mean() / luminance(trained ** 2.2)[mask].mean()
            cells.append(f"{psnr(img, trained):.1f} dB, ×{ratio:.3f}")
        print(f"| {Path(path).name} | " + " | ".join(cells) + " |")
        r.release()
    print()
    print("| HDR scene | " + " | ".join(f"{n}: clipped / crushed" for n in ["clip", *adaptive]) + " |")
    print("|---|" + "---|" * (len(adaptive) + 1))
    for scene, r, cams in scenes(width, height, 1, 0.0):
        frame = r.render(cams[0], Lens(1.0, 0.0))
        cells = [clipped_crushed(r.display_image(Tonemap(operator=OPERATORS[n]())), frame.alpha) for n in ["clip", *adaptive]]
        print(f"| {scene} | " + " | ".join(f"{100 * c:.1f}% / {100 * k:.1f}%" for c, k in cells) + " |")
        r.release()


def plot(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(results)
    fig, axes = plt.subplots(1, len(names), figsize=(6.0 * len(names), 4.0), squeeze=False)
    for ax, scene in zip(axes[0], names):
        ops = list(dict.fromkeys(op for op, _ in results[scene]))
        modes = list(dict.fromkeys(mode for _, mode in results[scene]))
        for (op, mode), r in results[scene].items():
            ax.plot(range(1, len(r["curve"]) + 1), r["curve"], ("-", "--", ":", "-.")[modes.index(mode) % 4],
                    color=f"C{ops.index(op)}", label=f"{op}, {mode}")
        ax.set_title(f"{scene}: display change from the tone curve alone")
        ax.set_xlabel("frame step along the orbit")
        ax.set_ylabel("mean |Δ| over corresponding pixels (8-bit levels)")
        ax.set_yscale("symlog", linthresh=0.1)
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m dofview.bench.tonemap_consistency", description=__doc__.split("\n\n")[0])
    p.add_argument("--frames", type=int, default=24)
    p.add_argument("--degrees", type=float, default=60.0, help="orbit angle over all frames (default 60)")
    p.add_argument("--width", type=int, default=200)
    p.add_argument("--height", type=int, default=150)
    p.add_argument("--fps", type=float, default=24.0, help="frame rate the smoothing assumes (default 24)")
    p.add_argument("--t0", type=float, nargs="+", default=[SMOOTHING_T0_S],
                   help=f"smoothing time constants, s (default {SMOOTHING_T0_S:g}, the viewer's and sequences')")
    p.add_argument("--plot", type=Path, default=ROOT / "docs" / "images" / "tonemap_consistency.png")
    p.add_argument("--fidelity", action="store_true",
                   help="instead: the trained look of the sRGB scenes and clipping on the HDR ones, at 0 EV")
    args = p.parse_args(argv)
    if args.frames < 2 or args.width < 8 or args.height < 8 or args.fps <= 0 or min(args.t0) <= 0:
        print("tonemap_consistency: error: --frames ≥ 2, --width/--height ≥ 8, --fps and --t0 > 0", file=sys.stderr)
        return 2
    if args.fidelity:
        fidelity(args.width, args.height)
        return 0
    adaptive = [n for n, c in OPERATORS.items() if c.adaptive]
    results: dict = {}
    print("| scene | operator | statistics | curve change (8-bit levels, mean / max step) | displayed change | worst clipped | worst crushed |")
    print("|---|---|---|---|---|---|---|")
    for scene, renderer, cams in scenes(args.width, args.height, args.frames, args.degrees):
        results[scene] = {}
        for name in adaptive:
            for t0 in [None, *args.t0]:
                mode = "per-frame" if t0 is None else f"smoothed t0={t0:g}s"
                r = measure(renderer, cams, OPERATORS[name](), t0, args.fps)
                results[scene][(name, mode)] = r
                print(f"| {scene} | {name} | {mode} | {np.mean(r['curve']):.3f} / {np.max(r['curve']):.3f} | "
                      f"{np.mean(r['shown']):.2f} | {100 * r['clipped']:.1f}% | {100 * r['crushed']:.1f}% |", flush=True)
        renderer.release()
    plot(results, args.plot)
    print(f"plot: {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
