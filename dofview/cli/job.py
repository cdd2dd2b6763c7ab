"""``dofview render``'s arguments turned into core objects once (:class:`RenderJob`): the scene
opened, the camera of every frame, the lens request, tone mapping, splatting settings, outputs and
the sequence asked for. :mod:`dofview.cli.render` and :mod:`dofview.cli.sequence` render a job;
neither reads the argparse Namespace again."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

from dofview.camera import Camera
from dofview.deep import DeepSettings
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.io.atomic import check_output_file, make_folder
from dofview.io.cameras import load_cameras_json
from dofview.lens import LensRequest
from dofview.rendering import Renderer
from dofview.request import (
    OpenedScene,
    camera_from_args,
    lens_request_from_args,
    open_scene,
    settings_from_args,
    tonemap_from_args,
)
from dofview.sequence import Outputs, camera_path, check_pattern, check_video, frame_name
from dofview.tonemap import Tonemap
from dofview.tonemap.stats import Stats


@dataclass
class RenderJob:
    """What one ``dofview render`` command asks for.

    Attributes:
        opened: the scene, its file, the cameras file in use and the notes to tell the user.
        path: the camera of each frame of the shot (one for a single image).
        focus: focus distance (scene units, inf allowed), "auto", or a pull (A, B) of those.
        lens: how the aperture was asked for.
        tonemap, settings: display and splatting settings.
        raster: the backend asked for (``--raster``).
        joint_stats: ``--stats joint`` (statistics pooled over the cameras file's views).
        lens_samples: > 0: the depth of field refined with that many sub-aperture passes (rendering.progressive).
        outputs: the EXR (+ PNG, video) names, patterns for a sequence.
        sequence: the options ask for a sequence (numbered frames) rather than one image.
        frames: the frames to render, 0-based (all of a single image's one).
        resume: keep finished frames whose headers agree (``--resume``).
        follow_views: the focus follows each view of a camera path (``--views`` with auto focus).
        deep: how ``outputs.deep``'s samples are made (``--deep-tolerance``, ``--deep-cap``).
    """

    opened: OpenedScene
    path: list[Camera]
    focus: float | str | tuple
    lens: LensRequest
    tonemap: Tonemap
    settings: RenderSettings
    raster: str
    joint_stats: bool
    lens_samples: int
    outputs: Outputs
    sequence: bool
    frames: range
    resume: bool = False
    follow_views: bool = False
    deep: DeepSettings = DeepSettings()

    def stats(self, renderer: Renderer) -> Stats | None:
        """The tone-mapping statistics ``--stats`` asks for: pooled over every training view of
        the cameras file (``joint``, for sequences that must not adapt), or None for each frame's own.

        Raises:
            DofviewError: ``--stats joint`` without a cameras file.
        """
        if not self.joint_stats or not self.tonemap.operator.adaptive:
            return None
        if self.opened.cameras is None:
            raise DofviewError("--stats joint pools the views of --cameras: give --cameras")
        from dofview.api import joint_stats

        return joint_stats(renderer, load_cameras_json(self.opened.cameras), self.tonemap.operator, self.settings)


def is_sequence(args: argparse.Namespace) -> bool:
    """Whether the render options ask for a sequence rather than one image."""
    return (isinstance(args.focus, tuple) or args.frames is not None or args.views is not None
            or args.frame_range is not None or args.resume or args.video is not None)


def job_from_args(args: argparse.Namespace) -> RenderJob:
    """The :class:`RenderJob` of ``dofview render``'s parsed arguments, every one checked before
    anything is rendered (bad values: one-line DofviewErrors).

    Raises:
        DofviewError: a bad output name, conflicting options, a missing file, a view out of range.
    """
    check_outputs(args)
    deep = deep_from_args(args)
    sequence = is_sequence(args)
    pull = isinstance(args.focus, tuple)
    if sequence:
        if pull and args.frames is None:
            raise DofviewError("--focus A:B (a focus pull) needs --frames N")
        if args.frames is not None and args.frames > 1 and not pull and args.views is None:
            raise DofviewError("--frames N needs something to change: --focus A:B (a focus pull) or --views I:J")
    settings = settings_from_args(args)
    lens = lens_request_from_args(args)
    opened = open_scene(args)
    tm = tonemap_from_args(args, opened.scene.colour_space)  # --tonemap auto follows the scene
    if args.views is not None:
        cameras, first, last = _views(args, opened)
        count = args.frames or abs(last - first) + 1
        start = camera_from_args(args, opened, view=str(first))  # view `first` at the size asked for
        path = camera_path(cameras, first, last, count, (start.width, start.height))
    else:
        count = args.frames or 1
        path = [camera_from_args(args, opened)] * count
    if lens.blur is not None:  # its bound, before any pass is rendered
        lens.blur.radius_px(path[0].width, path[0].ref_width)
    if count > 1:
        check_pattern(args.output, "-o")
        if args.png is not None:
            check_pattern(args.png, "--png")
        if args.deep is not None:
            check_pattern(args.deep, "--deep")
    first_frame, last_frame = args.frame_range or (0, count - 1)
    if first_frame >= count:
        raise DofviewError(f"--range {first_frame}:{last_frame}: the shot has frames 0…{count - 1}")
    last_frame = min(last_frame, count - 1)  # a farm's last chunk may run past the end (fixed chunk sizes)
    if args.video is not None and (first_frame, last_frame) != (0, count - 1):
        raise DofviewError("--video needs the whole shot: render the ranges first, then once more with "
                           "--resume --video")
    for _, target in _output_files(args):  # everything checked: the output folders are made, as renderers do
        make_folder(target)
    return RenderJob(opened, path, args.focus, lens, tm, settings, args.raster, args.stats == "joint",
                     args.lens_samples, Outputs(args.output, args.png, args.video, args.fps, args.half, args.deep),
                     sequence, range(first_frame, last_frame + 1), args.resume,
                     follow_views=args.views is not None, deep=deep)


def deep_from_args(args: argparse.Namespace) -> DeepSettings:
    """``--deep-tolerance`` and ``--deep-cap`` as :class:`DeepSettings`; the deep image refuses
    ``--lens-samples`` (it is one pass) and an output that is ``-o``'s own file."""
    given = {name: value for name, value in (("tolerance", args.deep_tolerance), ("cap", args.deep_cap))
             if value is not None}
    if given and args.deep is None:
        raise DofviewError(f"--deep-{next(iter(given))} shapes the deep image: it needs --deep OUT.exr")
    deep = DeepSettings(**given)
    if args.deep is not None:
        if args.lens_samples:
            raise DofviewError("--deep cannot be refined with --lens-samples: the deep image is one pass")
        if args.deep.resolve() == args.output.resolve():
            raise DofviewError(f"{args.deep}: --deep must name another file than -o")
    return deep


def _views(args: argparse.Namespace, opened: OpenedScene) -> tuple[list[Camera], int, int]:
    if args.eye or args.target:
        raise DofviewError("use either --views or --eye/--target, not both")
    if opened.cameras is None:
        raise DofviewError("--views needs training views: --cameras cameras.json, or a run folder that has one")
    cameras = load_cameras_json(opened.cameras)
    first, last = (0, len(cameras) - 1) if args.views == "all" else args.views
    for i in (first, last):
        if i >= len(cameras):
            raise DofviewError(f"{opened.cameras}: --views index {i} out of range (0…{len(cameras) - 1})")
    return cameras, first, last


def check_outputs(args: argparse.Namespace) -> None:
    """Every output path, before anything is rendered (so a bad --png leaves no EXR behind): the
    right ending, a place this process can write in (a missing folder is made once every option
    is checked; one under a file, or in /sys, is an error now), and not a folder itself. A
    sequence's numbered names are checked with frame 0 filled in."""
    if args.output.suffix.lower() != ".exr":
        raise DofviewError(f"{args.output}: output must be an .exr file")
    if args.deep is not None and args.deep.suffix.lower() != ".exr":
        raise DofviewError(f"{args.deep}: --deep must name an .exr file")
    if args.png is not None and args.png.suffix.lower() != ".png":
        raise DofviewError(f"{args.png}: --png must name a .png file")
    if args.video is not None:
        check_video(args.video)
    for given, target in _output_files(args):
        check_output_file(target, shown=given)


def _output_files(args: argparse.Namespace) -> list[tuple[Path, Path]]:
    """(output option's value, the file it names): frame 0's for a sequence's numbered names."""
    numbered, files = is_sequence(args), []
    for path in (args.output, args.png, args.video, args.deep):
        if path is None:
            continue
        try:
            files.append((path, frame_name(path, 0) if numbered and path is not args.video else path))
        except (TypeError, ValueError):  # no frame number (check_pattern says so): checked as written
            files.append((path, path))
    return files

