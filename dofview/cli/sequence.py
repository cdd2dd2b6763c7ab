"""``dofview render`` sequences: the options (--frames, --focus A:B, --views, --range, --resume,
--video) and the shot they describe; the rendering itself is :mod:`dofview.sequence`."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from dofview.camera import Camera
from dofview.cli.job import RenderJob
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.options import number
from dofview.rendering import Renderer
from dofview.sequence import Shot, focus_pull, render_sequence
from dofview.tonemap import Tonemap


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


def focus_and_span(renderer: Renderer, camera: Camera, settings: RenderSettings, scene: Path,
                   focus: float | str, span: bool,
                   tonemap: Tonemap | None = None) -> tuple[float, tuple[float, float] | None]:
    """``focus`` resolved on ``camera`` ("auto": the depth under the image centre, or nearest to
    it) and, when ``span``, the (near, far) depths in view (scene units) that ``--blur`` is measured
    on (:func:`dofview.rendering.focus.blur_span`: where the picture ``tonemap`` shows has detail), from pinhole
    passes (none when neither is needed). The depths are measured at the camera's reference width,
    so that the same command at any size resolves the same strength, scaled."""
    from dofview.rendering.focus import auto_focus, blur_span

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
    depths = blur_span(frame, tonemap)
    if depths is None:
        raise DofviewError(f"{scene}: the view is empty, --blur has no depths to measure; give --aperture")
    return float(focus), depths


def auto_focus_at(renderer: Renderer, camera: Camera, settings: RenderSettings, scene: Path) -> float:
    """``--focus auto`` for ``camera``: the depth under the image centre (or nearest to it)."""
    return focus_and_span(renderer, camera, settings, scene, "auto", False)[0]


def run_sequence(job: RenderJob) -> int:
    """Render the frames of ``job``'s shot (its focus pull and/or camera path)."""
    from dofview.rendering import get_backend

    path, frames, scene_path = job.path, job.frames, job.opened.path
    renderer = get_backend(job.raster, job.opened.scene)
    count = len(path)
    if isinstance(job.focus, tuple):
        ends = [auto_focus_at(renderer, path[i], job.settings, scene_path) if f == "auto" else f
                for f, i in zip(job.focus, (0, -1))]
        focuses = focus_pull(ends[0], ends[1], count)
    elif job.focus == "auto":
        focuses = [auto_focus_at(renderer, path[0], job.settings, scene_path)] * count if not job.follow_views else [
            auto_focus_at(renderer, cam, job.settings, scene_path) if i in frames else math.nan
            for i, cam in enumerate(path)]
    else:
        focuses = [float(job.focus)] * count
    shots = [Shot(i, cam, f) for i, (cam, f) in enumerate(zip(path, focuses))]
    if job.lens.blur is not None:  # one strength for the shot, from frame 0 whatever --range: every chunk agrees
        first_focus, span = focus_and_span(renderer, path[0], job.settings, scene_path,
                                           "auto" if math.isnan(focuses[0]) else focuses[0], job.lens.needs_span,
                                           job.tonemap)
        aperture = job.lens.lens(path[0], first_focus, span).aperture

        def lens_for(cam: Camera, focus: float) -> Lens:
            return Lens(focus, aperture)
    else:
        def lens_for(cam: Camera, focus: float) -> Lens:
            return job.lens.lens(cam, focus)
    job.opened.say_notes()
    render_sequence(renderer, shots, lens_for, job.tonemap, job.settings, str(scene_path), job.outputs, frames,
                    job.resume, job.lens.to_dict(), log=lambda line: print(line, file=sys.stderr),
                    stats=job.stats(renderer), lens_samples=job.lens_samples, deep=job.deep)
    return 0
