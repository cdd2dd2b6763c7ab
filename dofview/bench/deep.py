"""Deep output measured (issue 29, docs/BENCHMARKS.md "Deep output", docs/COMPOSITING.md).

    python -m dofview.bench.deep SCENE[:EYE:TARGET[:UP]] SCENE@CAMERAS.json … [--width 480] [--raster compute]
                                 [--tolerance 0.003,0.01,0.03] [--colour-space linear] [--aperture 20]

For each scene (framed automatically, from EYE=x,y,z to TARGET=x,y,z with world UP (default
0,-1,0) and a 70° field of view, or the first view of a cameras.json) and each tolerance, in
one process: the samples per pixel (mean over all pixels and over covered ones, 99th percentile,
most), the deep file's size per megapixel, its write time over the flat EXR's on the same frame,
the deep pass's time over the flat render's, flatten(deep) against the flat EXR, the same with
each sample decoded on its own (the alternative dofview.deep explains away), and a CG card
inserted at a depth between two layers (:func:`gap_depth`), merged in deep and flattened,
against a render of the scene with the card added as Gaussians. Prints a markdown table.
``--aperture A`` (as ``dofview render``'s, px at an 800 px wide frame): the default sliced depth of
field focused at the median Z of the pinhole frame's covered pixels instead of the pinhole (no card).
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from dofview.api import exr_header, load, load_cameras, save_deep
from dofview.bench.metrics import psnr
from dofview.bench.primitives import dc_from_colour
from dofview.camera import Camera, framing_camera, look_at
from dofview.deep import DeepFrame, DeepSettings
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering import get_backend
from dofview.scene import GaussianScene, quat_from_matrix
from dofview.tonemap import Tonemap, decode, encode

CARD_COLOUR = (0.2, 0.7, 0.3)


def card(camera: Camera, depth: float, like: GaussianScene,
         box: tuple[float, float, float, float] = (0.1, 0.6, 0.2, 0.9), colour: tuple[float, float, float] = CARD_COLOUR,
         spacing_px: float = 1.5, opacity: float = 0.9) -> GaussianScene:
    """A synthetic CG card as Gaussians: a plane facing ``camera`` at camera depth ``depth`` (scene
    units) over ``box`` (x0, x1, y0, y1, fractions of the image from its top-left corner), flat
    splats every ``spacing_px`` pixels of opacity ``opacity`` and base colour ``colour``, in the SH
    degree and colour space of ``like``."""
    x0, x1, y0, y1 = (f * s for f, s in zip(box, (camera.width, camera.width, camera.height, camera.height)))
    px, py = np.meshgrid(np.arange(x0, x1, spacing_px), np.arange(y0, y1, spacing_px))
    cam = np.stack([(px.ravel() - camera.cx) / camera.fx * depth, (py.ravel() - camera.cy) / camera.fy * depth,
                    np.full(px.size, depth)], 1)
    n = len(cam)
    side = spacing_px / camera.fx * depth
    rest = None if like.sh_rest is None else np.zeros((n, like.sh_rest.shape[1], 3), np.float32)
    return GaussianScene((cam - camera.T) @ camera.R, np.tile(quat_from_matrix(camera.R.T), (n, 1)),
                         np.tile([0.8 * side, 0.8 * side, 0.01 * side], (n, 1)), np.full(n, opacity),
                         np.tile(dc_from_colour(np.array(colour)), (n, 1)), rest, like.colour_space)


def joined(a: GaussianScene, b: GaussianScene) -> GaussianScene:
    """One scene holding ``a``'s Gaussians and then ``b``'s (the same SH degree)."""
    rest = None if a.sh_rest is None else np.concatenate([a.sh_rest, b.sh_rest])
    return GaussianScene(*(np.concatenate([getattr(a, k), getattr(b, k)])
                           for k in ("means", "quats", "scales", "opacities", "sh_dc")), rest, a.colour_space)


def gap_depth(image: DeepFrame) -> float:
    """A camera depth between two layers of ``image``: of 200 depths spaced evenly in log between
    the 5th and 95th percentiles of its samples' front depths, the one with most pixels holding
    samples on both sides of it, less ten for every pixel with a sample that spans it (Z < d <
    ZBack: a merge takes samples whole, so it cannot put anything inside one)."""
    pix = np.repeat(np.arange(image.counts.size), image.counts.ravel())
    front_z, back_z = image.depth[:, 0], image.depth[:, 1]
    best, depth = -math.inf, float(np.median(front_z))
    for d in np.geomspace(*np.percentile(front_z, [5, 95]), 200):
        front = np.zeros(image.counts.size, bool)
        back = np.zeros(image.counts.size, bool)
        front[pix[back_z < d]] = True
        back[pix[front_z > d]] = True
        spanning = np.unique(pix[(front_z < d) & (back_z > d)]).size
        score = float((front & back).sum()) - 10.0 * spanning
        if score > best:
            best, depth = score, float(d)
    return depth


def decoded_per_sample(image: DeepFrame) -> DeepFrame:
    """``image`` (an encoded scene's telescoped samples) with each sample instead decoded on its
    own: its colour in the blend space, unpremultiplied, decoded, premultiplied again. The
    alternative dofview.deep does not take, for measuring what it would cost."""
    h, w = image.shape
    start = image.offsets[:-1]
    counts = image.counts.ravel()
    linear, encoded_before = np.zeros((h * w, 3)), np.zeros((h * w, 3))
    trans = np.ones(h * w)
    rgba = image.rgba.astype(np.float64).copy()
    for k in range(int(counts.max()) if counts.size else 0):
        px = np.nonzero(counts > k)[0]
        s = start[px] + k
        linear[px] += trans[px, None] * rgba[s, :3]
        after = encode(linear[px])  # the blend's running sum in its own space
        # this sample's premultiplied colour in the blend's own space
        own = (after - encoded_before[px]) / np.maximum(trans[px, None], 1e-30)
        alpha = image.rgba[s, 3].astype(np.float64)
        rgba[s, :3] = decode(own / np.maximum(alpha[:, None], 1e-30)) * alpha[:, None]
        encoded_before[px] = after
        trans[px] *= 1.0 - alpha
    return DeepFrame(image.counts, rgba, image.depth)


def measure(scene: GaussianScene, camera: Camera, raster: str, deep: DeepSettings, folder: Path,
            repeats: int = 3, aperture: float = 0.0) -> dict[str, float]:
    """One scene, view and tolerance: the figures of the module docstring (times: the median of
    ``repeats`` runs of each, flat and deep taken in turn, after one unmeasured run of each);
    ``aperture`` > 0: the sliced depth of field's, A = ``aperture`` px at an 800 px wide frame."""
    renderer = get_backend(raster, scene)
    lens, settings = Lens(1.0, 0.0), RenderSettings()
    if aperture > 0:
        frame = renderer.render(camera, lens, settings)
        covered = frame.depth[frame.rgba[..., 3] > 0.5]
        lens = Lens(float(np.median(covered)) if covered.size else 1.0, aperture * camera.width / 800.0)
    header = exr_header(camera, lens, Tonemap(), settings, scene.colour_space, "scene")
    flat_path, deep_path = folder / "flat.exr", folder / "deep.exr"
    times: dict[str, list[float]] = {"render": [], "deep": [], "write": [], "write_deep": []}
    try:
        for run in range(repeats + 1):
            t0 = time.perf_counter()
            frame = renderer.render(camera, lens, settings)
            t1 = time.perf_counter()
            image = renderer.deep(camera, lens, settings, deep)
            t2 = time.perf_counter()
            frame.meta = header
            frame.save_exr(flat_path)
            t3 = time.perf_counter()
            save_deep(image, deep_path, header, deep, 0.0)
            t4 = time.perf_counter()
            if run:  # the first run compiles shaders and sorts
                for key, dt in zip(times, (t1 - t0, t2 - t1, t3 - t2, t4 - t3)):
                    times[key].append(dt)
    finally:
        renderer.release()
    med = {k: float(np.median(v)) for k, v in times.items()}
    megapixels = camera.width * camera.height / 1e6
    peak = max(1.0, float(frame.rgba.max()))
    stats = image.sample_stats()
    covered = image.counts[image.counts > 0]
    out = {"mean": stats["mean"], "mean_covered": float(covered.mean()) if covered.size else 0.0,
           "p99": stats["p99"], "max": stats["max"], "mb_per_mp": deep_path.stat().st_size / 1e6 / megapixels,
           "flat_mb_per_mp": flat_path.stat().st_size / 1e6 / megapixels,
           "write_ratio": med["write_deep"] / med["write"], "render_ratio": med["deep"] / med["render"],
           "flatten_db": psnr(DeepFrame.load(deep_path).flatten(), frame.rgba, peak)}
    encoded = scene.colour_space == "srgb"
    out["per_sample_db"] = psnr(decoded_per_sample(image).flatten(), frame.rgba, peak) if encoded else math.nan
    out["card_db"], out["card_depth"] = card_insertion(scene, camera, raster, image) if aperture == 0 else (math.nan,
                                                                                                          math.nan)
    out["layers"] = len(renderer.sliced_layers) if aperture > 0 else 0
    return out


def card_insertion(scene: GaussianScene, camera: Camera, raster: str, image: DeepFrame) -> tuple[float, float]:
    """(PSNR of the deep merge against the truth, the card's depth): :func:`card` at
    :func:`gap_depth` of ``image``, rendered deep on its own, merged into ``image`` and flattened,
    against the flat render of the scene with the card's Gaussians added."""
    depth = gap_depth(image)
    plate = card(camera, depth, scene)
    renderer = get_backend(raster, plate)
    try:
        merged = image.merge(renderer.deep(camera)).flatten()
    finally:
        renderer.release()
    renderer = get_backend(raster, joined(scene, plate))
    try:
        truth = renderer.render(camera, Lens(1.0, 0.0)).rgba
    finally:
        renderer.release()
    return psnr(merged, truth, max(1.0, float(truth.max()))), depth


def _view(spec: str, width: int, colour_space: str | None = None) -> tuple[GaussianScene, Camera, str]:
    if "@" in spec:
        path, cameras = spec.split("@")
        view = load_cameras(cameras)[0]
        return (load(path, colour_space=colour_space), view.resized(width, round(view.height * width / view.width)),
                Path(path).name)
    path, *where = spec.split(":")
    scene = load(path, colour_space=colour_space)
    height = width * 3 // 4
    if where:
        eye, target, *up = (np.array([float(v) for v in p.split(",")]) for p in where)
        return scene, look_at(eye, target, width, height, 70.0, *up), Path(path).name
    return scene, framing_camera(scene, width, height), Path(path).name


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenes", nargs="+", help="scene files, each optionally :EYE:TARGET (x,y,z scene units)")
    p.add_argument("--width", type=int, default=480)
    p.add_argument("--raster", default="compute")
    p.add_argument("--tolerance", default="0.01", help="comma-separated relative tolerances")
    p.add_argument("--colour-space", choices=("srgb", "linear"), help="read the scenes as this (default: as they say)")
    p.add_argument("--repeats", type=int, default=3, help="timed runs of each variant (the median is taken)")
    p.add_argument("--aperture", type=float, default=0.0, help="the sliced depth of field's aperture (px at 800 px)")
    args = p.parse_args(argv)
    print("| scene | tolerance | samples/px mean (covered) | p99 | max | deep MB/MP (flat) | write ÷ flat | "
          "deep pass ÷ flat render | flatten dB | per-sample decode dB | card dB (depth) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for spec in args.scenes:
            scene, camera, name = _view(spec, args.width, args.colour_space)
            for tol in (float(t) for t in args.tolerance.split(",")):
                m = measure(scene, camera, args.raster, DeepSettings(tol), Path(tmp), args.repeats, args.aperture)
                label = f"{name} ({m['layers']} layers)" if args.aperture else name
                print(f"| {label} | {tol:g} | {m['mean']:.2f} ({m['mean_covered']:.2f}) | {m['p99']:.0f} | {m['max']} | "
                      f"{m['mb_per_mp']:.1f} ({m['flat_mb_per_mp']:.1f}) | {m['write_ratio']:.2f} | "
                      f"{m['render_ratio']:.2f} | {m['flatten_db']:.1f} | {m['per_sample_db']:.1f} | "
                      f"{m['card_db']:.1f} ({m['card_depth']:.3g}) |", flush=True)


if __name__ == "__main__":
    main()
