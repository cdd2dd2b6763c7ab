"""``dofview render`` sequences: the options (--frames, --focus A:B, --views, --range, --resume,
--video) and the shot they describe; the rendering itself is :mod:`dofview.sequence`."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.io.cameras import load_cameras_json
from dofview.lens import Lens
from dofview.options import (
    aperture_asked,
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
from dofview.rendering import Renderer
from dofview.sequence import (
    Outputs,
    Shot,
    camera_path,
    check_pattern,
    focus_pull,
    render_sequence,
)


def _pair(text: str, what: str, example: str) -> tuple[str, str]:
    first, sep, last = text.partition(":")
    if not sep or not first or not last:
        raise argparse.ArgumentTypeError(f"{what} must be written {example}, got {text!r}")
    return first, last


def views_value(text: str) -> tuple[int, int] | str:
    """``I:J`` (view indices, either order) or ``all``."""
    if text == "all":
        return text
    index = number(0, None, integer=True, what="view index")
    first, last = _pair(text, "--views", "I:J (view indices) or all")
    return index(first), index(last)


def range_value(text: str) -> tuple[int, int]:
    """``S:E``: frames S to E, both included, 0-based."""
    index = number(0, None, integer=True, what="frame number")
    first, last = (index(t) for t in _pair(text, "--range", "S:E (first and last frame, from 0)"))
    if last < first:
        raise argparse.ArgumentTypeError(f"--range {text}: the last frame comes before the first")
    return first, last


def add_sequence_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("sequence (output names number their frames: -o out/f_%04d.exr --png out/f_%04d.png)")
    g.add_argument("--frames", type=number(1, None, integer=True, what="frame count"),
                   help="frames of the sequence: a focus pull (--focus A:B, even in 1/z) and/or a camera path "
                        "(--views)")
    g.add_argument("--views", type=views_value,
                   help="I:J or all: a camera path through views I…J of cameras.json (slerped rotations, "
                        "interpolated positions and intrinsics); default one frame per view")
    g.add_argument("--range", type=range_value, dest="frame_range", metavar="S:E",
                   help="render frames S…E only (0-based, inclusive; E past the end stops at the last frame): "
                        "one chunk of a shot spread over machines")
    g.add_argument("--resume", action="store_true",
                   help="skip frames whose files are already there and whose headers record this command's camera, "
                        "lens and settings; render the others again")
    g.add_argument("--video", type=Path, help="also put the frames together as an H.264 video (.mp4, .mov, .mkv; "
                                              "needs imageio-ffmpeg: pip install 'dofview[video]')")
    g.add_argument("--fps", type=number(0, None, lo_open=True, what="frame rate"), default=24.0,
                   help="video frame rate (default 24)")


def is_sequence(args: argparse.Namespace) -> bool:
    """Whether the render options ask for a sequence rather than one image."""
    return (isinstance(args.focus, tuple) or args.frames is not None or args.views is not None
            or args.frame_range is not None or args.resume or args.video is not None)


def lens_info(args: argparse.Namespace) -> dict[str, object]:
    """What an EXR header records of the lens options besides the strength used: the physical-lens
    values and the aperture as asked (``asked``: e.g. "--blur 1%")."""
    return {"fnumber": args.fnumber, "focal_mm": args.focal_mm, "sensor_mm": args.sensor_mm,
            "units_per_metre": args.units_per_metre, "asked": aperture_asked(args)}


def focus_and_span(renderer: Renderer, camera: Camera, settings: RenderSettings, scene: Path,
                   focus: float | str, span: bool) -> tuple[float, tuple[float, float] | None]:
    """``focus`` resolved on ``camera`` ("auto": the depth under the image centre, or nearest to
    it) and, when ``span``, the (near, far) depths in view (scene units) that ``--blur`` is measured
    on, from pinhole passes (none when neither is needed). The depths are measured at the camera's
    reference width, so that the same command at any size resolves the same strength, scaled."""
    from dofview.rendering.focus import auto_focus, depth_range

    pinhole = Lens(1.0, 0.0)
    frame = renderer.render(camera, pinhole, settings) if focus == "auto" else None
    if frame is not None:
        focus = auto_focus(frame)
        if focus is None:
            raise DofviewError(f"{scene}: the view is empty, nothing to focus on; give --focus")
    if not span:
        return float(focus), None
    if camera.width != camera.ref_width:
        height = max(1, round(camera.height * camera.ref_width / camera.width))
        frame = renderer.render(camera.resized(camera.ref_width, height), pinhole, settings)
    elif frame is None:
        frame = renderer.render(camera, pinhole, settings)
    depths = depth_range(frame)
    if depths is None:
        raise DofviewError(f"{scene}: the view is empty, --blur has no depths to measure; give --aperture")
    return float(focus), depths


def auto_focus_at(renderer: Renderer, camera: Camera, settings: RenderSettings, scene: Path) -> float:
    """``--focus auto`` for ``camera``: the depth under the image centre (or nearest to it)."""
    return focus_and_span(renderer, camera, settings, scene, "auto", False)[0]


def _views(args: argparse.Namespace) -> tuple[list[Camera], int, int]:
    if args.eye or args.target:
        raise DofviewError("use either --views or --eye/--target, not both")
    if args.cameras is None:
        raise DofviewError("--views needs training views: --cameras cameras.json, or a run folder that has one")
    cameras = load_cameras_json(args.cameras)
    first, last = (0, len(cameras) - 1) if args.views == "all" else args.views
    for i in (first, last):
        if i >= len(cameras):
            raise DofviewError(f"{args.cameras}: --views index {i} out of range (0…{len(cameras) - 1})")
    return cameras, first, last


def run_sequence(args: argparse.Namespace) -> int:
    from dofview.rendering import get_backend

    pull = isinstance(args.focus, tuple)
    if pull and args.frames is None:
        raise DofviewError("--focus A:B (a focus pull) needs --frames N")
    if args.frames is not None and args.frames > 1 and not pull and args.views is None:
        raise DofviewError("--frames N needs something to change: --focus A:B (a focus pull) or --views I:J")
    settings = settings_from_args(args)
    scene = load_scene_arg(args)
    tm = tonemap_from_args(args, scene.colour_space)  # --tonemap auto follows the scene
    if args.views is not None:
        cameras, first, last = _views(args)
        frames = args.frames or abs(last - first) + 1
        args.view = str(first)
        start = camera_from_args(args, scene)  # view `first` at the size asked for
        path = camera_path(cameras, first, last, frames, (start.width, start.height))
    else:
        frames = args.frames or 1
        path = [camera_from_args(args, scene)] * frames
    if frames > 1:
        check_pattern(args.output, "-o")
        if args.png is not None:
            check_pattern(args.png, "--png")
    first_frame, last_frame = args.frame_range or (0, frames - 1)
    if first_frame >= frames:
        raise DofviewError(f"--range {first_frame}:{last_frame}: the shot has frames 0…{frames - 1}")
    last_frame = min(last_frame, frames - 1)  # a farm's last chunk may run past the end (fixed chunk sizes)
    if args.video is not None and (first_frame, last_frame) != (0, frames - 1):
        raise DofviewError("--video needs the whole shot: render the ranges first, then once more with "
                           "--resume --video")

    renderer = get_backend(args.raster, scene)
    if pull:
        ends = [auto_focus_at(renderer, path[i], settings, args.scene) if f == "auto" else f
                for f, i in zip(args.focus, (0, -1))]
        focuses = focus_pull(ends[0], ends[1], frames)
    elif args.focus == "auto":
        fixed = args.views is None  # one camera: one focus; a path: the focus follows each view
        focuses = [auto_focus_at(renderer, path[0], settings, args.scene)] * frames if fixed else [
            auto_focus_at(renderer, cam, settings, args.scene) if first_frame <= i <= last_frame else math.nan
            for i, cam in enumerate(path)]
    else:
        focuses = [float(args.focus)] * frames
    shots = [Shot(i, cam, f) for i, (cam, f) in enumerate(zip(path, focuses))]
    out = Outputs(args.output, args.png, args.video, args.fps, args.half)
    if args.blur is not None:  # one strength for the shot, from frame 0 whatever --range: every chunk agrees
        first_focus, span = focus_and_span(renderer, path[0], settings, args.scene,
                                           "auto" if math.isnan(focuses[0]) else focuses[0], needs_depths(args))
        aperture = lens_from_args(args, path[0], first_focus, span).aperture

        def lens_for(cam: Camera, focus: float) -> Lens:
            return Lens(focus, aperture)
    else:
        def lens_for(cam: Camera, focus: float) -> Lens:
            return lens_from_args(args, cam, focus)
    say_notes(args)
    render_sequence(renderer, shots, lens_for, tm, settings,
                    str(args.scene), out, range(first_frame, last_frame + 1), args.resume, lens_info(args),
                    log=lambda line: print(line, file=sys.stderr), stats=stats_from_args(args, renderer, tm, settings),
                    lens_samples=args.lens_samples)
    return 0
