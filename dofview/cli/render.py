"""``dofview render``: one view of a scene, headless, to a linear EXR (+ PNG)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from dofview.api import save_render
from dofview.cli.sequence import (
    add_sequence_args,
    focus_and_span,
    is_sequence,
    lens_info,
    run_sequence,
)
from dofview.errors import DofviewError
from dofview.options import (
    add_lens_args,
    add_scene_args,
    add_view_args,
    camera_from_args,
    lens_from_args,
    load_scene_arg,
    needs_depths,
    number,
    say_notes,
    settings_from_args,
    stats_from_args,
    tonemap_from_args,
)


def add_parser(sub) -> None:
    p = sub.add_parser("render", help="render a scene headless to a linear HDR EXR (+ PNG)",
                       description="Render a trained 3DGS scene with depth of field to an EXR holding linear "
                                   "R, G, B, A (premultiplied) and Z (camera depth), and optionally a PNG.")
    add_scene_args(p)
    p.add_argument("-o", "--output", type=Path, required=True, help="output EXR path")
    p.add_argument("--png", type=Path, help="also write the tonemapped image as PNG")
    p.add_argument("--half", action="store_true", help="store R, G, B, A as half floats (Z stays float32)")
    add_view_args(p)
    add_lens_args(p, focus_pull=True)
    p.add_argument("--lens-samples", type=number(1, None, integer=True, what="lens samples"), default=0,
                   help="render the physical thin lens as the average of N pinhole passes over the lens disk "
                        "(what the viewer converges to when still) instead of the single pass")
    add_sequence_args(p)
    p.set_defaults(run=run_render)


def run_render(args: argparse.Namespace) -> int:
    from dofview.rendering import get_backend

    check_outputs(args)
    if is_sequence(args):
        return run_sequence(args)
    settings = settings_from_args(args)
    scene = load_scene_arg(args)
    tm = tonemap_from_args(args, scene.colour_space)  # --tonemap auto follows the scene
    camera = camera_from_args(args, scene)
    renderer = get_backend(args.raster, scene)
    focus, span = focus_and_span(renderer, camera, settings, args.scene, args.focus, needs_depths(args))
    lens = lens_from_args(args, camera, focus, span)
    stats = stats_from_args(args, renderer, tm, settings)
    save_render(renderer, camera, lens, tm, settings, str(args.scene), args.output, args.png, half=args.half,
                lens_info=lens_info(args), stats=stats, lens_samples=args.lens_samples)
    say_notes(args)
    print(f"{args.output}: {camera.width}×{camera.height}, focus {lens.focus:.4g}, aperture A={lens.aperture:.4g}, "
          f"exposure {tm.exposure:+.4g} EV" + (f"; {args.png}" if args.png else ""), file=sys.stderr)
    return 0


def check_outputs(args: argparse.Namespace) -> None:
    """Every output path, before anything is rendered (so a bad --png leaves no EXR behind): the
    right ending, an existing folder that can be written to, and not a folder itself. A sequence's
    numbered names are checked with frame 0 filled in."""
    from dofview.sequence import check_video, frame_name

    if args.output.suffix.lower() != ".exr":
        raise DofviewError(f"{args.output}: output must be an .exr file")
    if args.png is not None and args.png.suffix.lower() != ".png":
        raise DofviewError(f"{args.png}: --png must name a .png file")
    if args.video is not None:
        check_video(args.video)
    numbered = is_sequence(args)
    for path in (args.output, args.png, args.video):
        if path is None:
            continue
        try:
            target = frame_name(path, 0) if numbered and path is not args.video else path
        except (TypeError, ValueError):  # no frame number (check_pattern says so): checked as written
            target = path
        folder = target.parent
        if not folder.is_dir():
            raise DofviewError(f"{path}: folder {folder} does not exist")
        if not os.access(folder, os.W_OK | os.X_OK):
            raise DofviewError(f"{path}: Permission denied: folder {folder} cannot be written to")
        if target.is_dir():
            raise DofviewError(f"{path}: is a folder, not a file name")
