"""``dofview train``, ``dofview make-dataset`` and ``dofview train-eval``.

This module imports without torch, so the commands always show in ``dofview --help``; running
``dofview train`` without torch installed is a one-line error naming the fix.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from dofview.errors import DofviewError, require_extra
from dofview.options import number, vec3
from dofview.request import open_scene

NO_TORCH = "dofview train needs torch: pip install 'dofview[train]' (a CPU build is enough)"


def add_parser(sub) -> None:
    p = sub.add_parser("train", help="fit an HDR Gaussian scene with depth of field to 8-bit photos (needs torch)",
                       description="Fit an all-in-focus HDR Gaussian scene to photos taken with varying exposure "
                                   "time, f-number and focus (Cinematic Gaussians); see docs/TRAINING.md.")
    p.add_argument("dataset", type=Path, help="dataset folder with transforms.json")
    p.add_argument("-o", "--output", type=Path, required=True, help="output .ply (linear HDR; sRGB for --variant ldr)")
    p.add_argument("--iterations", type=number(1, None, integer=True, what="iterations"), default=2000)
    p.add_argument("--warmup", type=number(0, None, integer=True, what="warm-up"), default=500,
                   help="exposure-aligned pinhole steps before tonemapping and depth of field (default 500)")
    p.add_argument("--gaussians", type=number(1, None, integer=True, what="initial Gaussians"), default=None,
                   help="initial random Gaussians, without SfM points (default: one per 16 pixels of a photo, "
                        "at most --max-gaussians)")
    p.add_argument("--max-gaussians", type=number(1, None, integer=True, what="max Gaussians"), default=1500)
    p.add_argument("--variant", choices=("full", "no-exp", "no-foc", "ldr"), default="no-foc",
                   help="full: Eq. 8 with L_exp and L_foc; no-foc (the default: L_foc lowered the held-out "
                        "scores, docs/TRAINING.md) and no-exp leave one out; ldr: a plain LDR fit")
    p.add_argument("--seed", type=number(0, None, integer=True, what="seed"), default=0)
    p.add_argument("--sh-degree", type=int, choices=(0, 1, 2, 3), default=0,
                   help="view-dependent colour: SH degree, bands added progressively (default 0: one radiance "
                        "per Gaussian, the fastest; docs/TRAINING.md)")
    p.add_argument("--device", choices=("auto", "cpu", "cuda"), default="auto")
    p.add_argument("--torch-raster", choices=("native", "sparse", "dense"),
                   help="the differentiable rasteriser the fit runs on (not a GL backend: --raster names those): "
                        "native (compositing in C, built on first use with the system C compiler; the default on "
                        "the CPU when it builds, the fastest: docs/TRAINING.md), sparse (plain torch per-pixel "
                        "fragment lists; the default otherwise) or dense (per tile, the test oracle)")
    p.add_argument("--checkpoint", type=Path, help="checkpoint file (default OUTPUT.ckpt)")
    p.add_argument("--checkpoint-every", type=number(0, None, integer=True, what="checkpoint interval"), default=500,
                   help="steps between checkpoints, 0 = none (default 500)")
    p.add_argument("--resume", action="store_true", help="continue from the checkpoint")
    p.add_argument("--log", type=Path, help="write the loss / Gaussian-count history as JSON")
    p.add_argument("--plot", type=Path, help="plot the loss and Gaussian count over time as PNG")
    p.set_defaults(run=run_train)

    p = sub.add_parser("make-dataset", help="render a training dataset (photos + transforms.json) from a scene",
                       description="Render random-exposure, random-aperture, random-focus 8-bit photos of a scene "
                                   "with dofview's renderer, plus held-out all-in-focus HDR views.")
    p.add_argument("scene", type=Path, help="scene (.ply or .splat)")
    p.add_argument("--colour-space", "--color-space", choices=("srgb", "linear"), help="override the scene's colour space")
    p.add_argument("-o", "--output", type=Path, required=True, help="new dataset folder")
    p.add_argument("--views", type=number(1, None, integer=True, what="views"), default=30)
    p.add_argument("--held-out", type=number(0, None, integer=True, what="held-out views"), default=8)
    p.add_argument("--width", type=number(8, None, integer=True, what="width"), default=64)
    p.add_argument("--height", type=number(8, None, integer=True, what="height"), default=48)
    p.add_argument("--focal-mm", type=number(0, None, lo_open=True, what="focal length"), default=50.0)
    p.add_argument("--sensor-mm", type=number(0, None, lo_open=True, what="sensor width"), default=36.0)
    p.add_argument("--units-per-metre", "--units-per-meter", type=_units_per_metre, default=None,
                   help="scene units per metre, which sets the physical lens's size in the scene (default auto: "
                        "chosen so that f/1.4 blurs the scene's depth by up to 2%% of the width, whatever its units)")
    p.add_argument("--ev-min", type=float, default=-10.0, help="lowest exposure, stops from mid-grey key (default -10)")
    p.add_argument("--ev-max", type=float, default=2.0, help="highest exposure, stops from the key (default 2)")
    p.add_argument("--orbit", type=number(0, 90, hi_open=False, what="orbit"), default=15.0,
                   help="cameras swing up to this many degrees of yaw (half of it in pitch) about the target")
    p.add_argument("--eye", type=vec3, help="base camera position x,y,z (default: a framing camera)")
    p.add_argument("--target", type=vec3, help="point the cameras look at x,y,z")
    p.add_argument("--seed", type=number(0, None, integer=True, what="seed"), default=0)
    p.add_argument("--points", type=number(0, None, integer=True, what="points"), default=0,
                   help="also write this many SfM-like points (noisy means of the scene's opaque Gaussians) "
                        "as COLMAP sparse/0/points3D.txt, which dofview train starts from (default 0: none)")
    _raster_option(p)
    p.set_defaults(run=run_make_dataset)

    p = sub.add_parser("train-eval", help="score trained scenes on a dataset's held-out HDR views",
                       description="Log-radiance PSNR and bright-light radiance ratio of each scene on the "
                                   "dataset's held-out all-in-focus HDR views; prints a Markdown table.")
    p.add_argument("dataset", type=Path)
    p.add_argument("scenes", type=Path, nargs="+")
    p.add_argument("--json", type=Path, help="also write the scores as JSON")
    _raster_option(p)
    p.set_defaults(run=run_eval)


def _raster_option(p: argparse.ArgumentParser) -> None:
    from dofview.rendering import BACKENDS

    p.add_argument("--raster", choices=("auto", *BACKENDS), default="quad",
                   help="renderer backend of the renders (default quad, the reference)")


def _units_per_metre(text: str) -> float | None:
    return None if text == "auto" else number(0, None, lo_open=True, what="units per metre")(text)


def _torch() -> None:
    try:
        import torch  # noqa: F401
    except ModuleNotFoundError:
        raise DofviewError(NO_TORCH) from None


def run_train(args: argparse.Namespace) -> int:
    _torch()
    from dofview.io.atomic import atomic_output, make_folder
    from dofview.io.ply import write_ply
    from dofview.train.dataset import load_dataset
    from dofview.train.optimise import TrainConfig, Trainer

    ckpt = args.checkpoint or args.output.with_suffix(".ckpt")
    outputs = _check_train_outputs(args, ckpt)
    if args.resume and not ckpt.is_file():
        raise DofviewError(f"{ckpt}: no checkpoint to resume from")
    dataset = load_dataset(args.dataset)
    config = TrainConfig(iterations=args.iterations, warmup=min(args.warmup, args.iterations), initial=args.gaussians,
                         max_gaussians=args.max_gaussians, variant=args.variant, seed=args.seed,
                         sh_degree=args.sh_degree)
    trainer = Trainer(dataset, config, args.device, args.torch_raster)
    for path in outputs:
        make_folder(path)
    if args.resume:
        trainer.load_checkpoint(ckpt)
    trainer.run(progress=True, checkpoint=ckpt, checkpoint_every=args.checkpoint_every)
    linear = args.variant != "ldr"
    write_ply(trainer.model.to_scene("linear" if linear else "srgb", args.output.stem), args.output)
    if args.log:
        with atomic_output(args.log) as tmp:
            tmp.write_text(json.dumps({"dataset": str(args.dataset), "variant": args.variant, "raster": trainer.raster,
                                       "history": trainer.history.rows, "scores": trainer.history.scores}, indent=1))
    rows = trainer.history.rows
    if args.plot:
        from dofview.train.plot import plot_history

        plot_history(rows, args.plot, f"dofview train {args.dataset.name} ({args.variant})")
    counts = " → ".join(str(r["gaussians"]) for r in rows[:: max(len(rows) // 6, 1)])
    scores = trainer.history.scores
    held_out = f"; held-out log-radiance PSNR {scores[-1]['log_psnr']:.2f} dB at step {scores[-1]['step']}" \
        if scores else ""
    print(f"{args.output}: {trainer.model.count} Gaussians ({'linear HDR' if linear else 'sRGB'}) after "
          f"{trainer.step} steps on {trainer.device} ({trainer.raster} rasteriser); count over time {counts}"
          f"{held_out}", file=sys.stderr)
    return 0


def _check_train_outputs(args: argparse.Namespace, ckpt: Path) -> list[Path]:
    """Every file training writes, checked before any step is taken (a run of minutes or hours
    must not end in a refusal to write its model); returns them, for their folders to be made
    once the dataset has loaded."""
    from dofview.io.atomic import check_output_file

    if args.output.suffix.lower() != ".ply":
        raise DofviewError(f"{args.output}: output must be a .ply file")
    if args.plot is not None:
        if args.plot.suffix.lower() != ".png":
            raise DofviewError(f"{args.plot}: --plot must name a .png file")
        require_extra("matplotlib", "bench", f"--plot {args.plot}")
    named = {"-o": args.output, "--checkpoint": ckpt, "--log": args.log, "--plot": args.plot}
    files = {option: path for option, path in named.items() if path is not None}
    taken: dict[Path, str] = {}
    for option, path in files.items():
        check_output_file(path)
        if path.resolve() in taken:
            raise DofviewError(f"{path}: {option} must name another file than {taken[path.resolve()]}")
        taken[path.resolve()] = option
    return list(files.values())


def run_make_dataset(args: argparse.Namespace) -> int:
    from dofview.train.generate import Capture, generate

    capture = Capture(views=args.views, held_out=args.held_out, width=args.width, height=args.height,
                      focal_mm=args.focal_mm, sensor_mm=args.sensor_mm, units_per_metre=args.units_per_metre,
                      ev_range=(args.ev_min, args.ev_max), orbit_deg=args.orbit, seed=args.seed,
                      points=args.points)
    scene = open_scene(args).scene
    path = generate(scene, args.output, capture, args.eye, args.target, raster=args.raster)
    points = f", {args.points} SfM-like points" if args.points else ""
    print(f"{path}: {args.views} photos, {args.held_out} held-out HDR views{points}", file=sys.stderr)
    print(blur_summary(json.loads(path.read_text())), file=sys.stderr)
    return 0


def blur_summary(doc: dict) -> str:
    """What lens a generated dataset's photos were taken with, and the blur they carry (the
    largest CoC radius, px, of each photo over what it sees)."""
    gen, frames = doc["generator"], [f for f in doc["frames"] if "max_coc_px" in f]
    upm = doc["units_per_metre"]
    how = (f"chosen so that f/{min(gen['f_numbers']):g} blurs the depth by up to {100 * gen['blur_fraction']:g}% of "
           "the width; --units-per-metre sets it") if gen.get("units_per_metre") == "auto" else "as given"
    focal = frames[0]["focal_length_mm"] if frames else float("nan")
    cocs = [f["max_coc_px"] for f in frames]
    lines = [f"lens: {focal:g} mm on a {doc['sensor_mm']:g} mm sensor, the scene at {upm:.4g} units per metre ({how})"]
    if cocs:
        lines.append(f"largest blur per photo (CoC radius, px): median {float(np.median(cocs)):.2f}, "
                     f"max {max(cocs):.2f}; " + " ".join(f"{c:.1f}" for c in cocs))
    return "\n".join(lines)


def run_eval(args: argparse.Namespace) -> int:
    from dofview.io import load_scene
    from dofview.io.atomic import atomic_output, check_output_file, make_folder
    from dofview.train.dataset import load_dataset
    from dofview.train.evaluate import evaluate

    if args.json is not None:  # before the scenes are rendered, not after
        check_output_file(args.json)
    dataset = load_dataset(args.dataset)
    if args.json is not None:
        make_folder(args.json)
    rows = []
    print("| scene | colour space | log-radiance PSNR (dB) | bright-region radiance ratio |")
    print("|---|---|---|---|")
    for path in args.scenes:
        scene = load_scene(path, progress=False)
        ev = evaluate(scene, dataset, args.raster)
        rows.append({"scene": str(path), "colour_space": scene.colour_space, "log_psnr": ev.log_psnr,
                     "mean_log_psnr": ev.mean_log_psnr, "bright_ratio": ev.bright_ratio,
                     "mean_bright_ratio": ev.mean_bright_ratio})
        print(f"| {path.name} | {scene.colour_space} | {ev.mean_log_psnr:.2f} | {ev.mean_bright_ratio:.3f} |")
    if args.json:
        with atomic_output(args.json) as tmp:
            tmp.write_text(json.dumps(rows, indent=1))
    return 0
