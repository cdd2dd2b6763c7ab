"""``dofview view``: the interactive desktop viewer (see docs/VIEWER.md for keys and panels)."""

from __future__ import annotations

import argparse
from pathlib import Path

DEFAULT_WINDOW = (1280, 800)


def add_parser(subparsers) -> None:
    from dofview.options import add_lens_args, add_scene_args, add_view_args

    p = subparsers.add_parser(
        "view", help="open a scene in the interactive viewer",
        description="Explore a trained 3DGS scene in a window and pull focus like a camera operator: live "
                    "focus, aperture and exposure on the same renderer as `dofview render`. Lens and camera "
                    "options set the starting state; --width/--height size the window. Press F1 for help.")
    add_scene_args(p)
    add_view_args(p, default_size=DEFAULT_WINDOW)
    add_lens_args(p)
    p.add_argument("--script", type=Path, help="run the actions of a JSON script, then close (tests, screenshots)")
    p.set_defaults(run=run_view)


def _initial_settings(args: argparse.Namespace, scene_colour_space: str):
    """Panel values from the render options (lens values beyond these come with the focus)."""
    from dofview.options import settings_from_args, tonemap_from_args
    from dofview.viewer.settings import ViewerSettings

    tm = tonemap_from_args(args)  # also refuses --shutter without --fnumber
    s = ViewerSettings(colour_space=scene_colour_space, render=settings_from_args(args), gamma=tm.gamma,
                       ev=args.exposure, background=tm.background, sensor_mm=args.sensor_mm,
                       units_per_metre=args.units_per_metre, tonemap_operator=tm.operator.name,
                       tonemap_params=tm.operator.params())
    s.physical = args.fnumber is not None or args.focal_mm is not None
    s.fnumber = args.fnumber or s.fnumber
    s.focal_mm = args.focal_mm or s.focal_mm
    if args.shutter is not None:
        s.exposure_follows_aperture, s.shutter_s = True, args.shutter
    return s


def run_view(args: argparse.Namespace) -> int:
    from dofview.io.cameras import load_cameras_json
    from dofview.options import (
        camera_from_args,
        lens_from_args,
        load_scene_arg,
        say_notes,
        up_from_args,
    )
    from dofview.viewer.script import ScriptRunner, load_script
    from dofview.viewer.settings import START_COC_PX
    from dofview.viewer.window import check_display

    check_display()
    actions = load_script(args.script) if args.script else None
    scene = load_scene_arg(args)
    cameras = load_cameras_json(args.cameras) if args.cameras else []
    settings = _initial_settings(args, scene.colour_space)
    if args.stats == "joint" and not cameras:
        from dofview.errors import DofviewError

        raise DofviewError("--stats joint pools the views of --cameras: give --cameras")
    start = camera_from_args(args, scene, DEFAULT_WINDOW)

    from dofview.viewer.viewer import Viewer
    from dofview.viewer.window import Window

    window = Window("dofview", args.width or DEFAULT_WINDOW[0], args.height or DEFAULT_WINDOW[1],
                    on_drop=lambda paths: viewer.open_file(paths[0]))
    viewer = Viewer(window, scene, args.scene, settings, start, cameras, None if cameras else up_from_args(args, scene),
                    raster=args.raster)
    say_notes(args)
    names = [c.name for c in cameras]
    if args.cameras and start.name in names:
        viewer.view_index = names.index(start.name)
    try:
        if args.focus == "auto":
            viewer.auto_focus()
        else:
            viewer.pinhole_pass(sort=True)  # the depths in view scale the sliders and the first aperture
            settings.focus = float(args.focus)
        lens = lens_from_args(args, viewer.camera(), settings.focus)  # refuses conflicting lens options
        settings.aperture = lens.aperture if args.aperture is not None or settings.physical \
            else viewer.aperture_for_blur(START_COC_PX)
        if args.stats == "joint" and settings.operator().adaptive:
            viewer.lock_joint_stats()
        runner = ScriptRunner(actions, str(args.script)) if actions is not None else None
        while not window.should_close:
            window.poll(None if runner or viewer.busy or viewer.fly_mode else 1 / 30)
            if runner:
                runner.step(viewer)
            viewer.frame()
    finally:
        viewer.close()
        window.destroy()
    return 0
