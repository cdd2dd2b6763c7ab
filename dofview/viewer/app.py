"""``dofview view``: the interactive desktop viewer (see docs/VIEWER.md for keys and panels)."""

from __future__ import annotations

import argparse
from dataclasses import replace
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
    """Panel values and the lens request from the render options (the aperture strength comes
    with the focus, once the first view is framed)."""
    from dofview.request import lens_request_from_args, settings_from_args, tonemap_from_args
    from dofview.tonemap import AUTO
    from dofview.viewer.settings import ViewerSettings

    tm = tonemap_from_args(args, scene_colour_space)  # also refuses --shutter without --fnumber
    request = lens_request_from_args(args)  # refuses conflicting lens options
    s = ViewerSettings(colour_space=scene_colour_space, render=settings_from_args(args), gamma=tm.gamma,
                       ev=args.exposure, background=tm.background, sensor_mm=request.sensor_mm,
                       units_per_metre=request.units_per_metre, tonemap_operator=tm.operator.name,
                       tonemap_params=tm.operator.params(), tonemap_auto=args.tonemap == AUTO)
    s.physical = request.physical is not None
    s.fnumber = request.fnumber or s.fnumber
    s.focal_mm = request.focal_mm or s.focal_mm
    if args.shutter is not None:
        s.exposure_follows_aperture, s.shutter_s = True, args.shutter
    return s, request


def run_view(args: argparse.Namespace) -> int:
    from dofview.io.cameras import load_cameras_json
    from dofview.request import camera_from_args, open_scene, up_from_args
    from dofview.viewer.script import ScriptRunner, load_script
    from dofview.viewer.window import check_display

    check_display()
    actions = load_script(args.script) if args.script else None
    opened = open_scene(args)
    scene = opened.scene
    cameras = load_cameras_json(opened.cameras) if opened.cameras else []
    settings, request = _initial_settings(args, scene.colour_space)
    if args.stats == "joint" and not cameras:
        from dofview.errors import DofviewError

        raise DofviewError("--stats joint pools the views of --cameras: give --cameras")
    start = camera_from_args(args, opened, DEFAULT_WINDOW)

    from dofview.viewer.viewer import Viewer
    from dofview.viewer.window import Window

    window = Window("dofview", args.width or DEFAULT_WINDOW[0], args.height or DEFAULT_WINDOW[1],
                    on_drop=lambda paths: viewer.model.open_file(paths[0]))
    viewer = Viewer(window, scene, opened.path, settings, start, cameras,
                    None if cameras else up_from_args(args, opened), raster=args.raster,
                    lod_set=opened.lod_set, budget=args.budget, lod=args.lod)
    opened.say_notes()
    names = [c.name for c in cameras]
    if opened.cameras and start.name in names:
        viewer.model.view_index = names.index(start.name)
    # R and U frame the scene as it opened without cameras (the size and field of view it was framed for)
    viewer.model.framing = (start.width, start.height, 50.0 if cameras else start.fov_x_deg)
    try:
        viewer.model.start_focus = None if args.focus == "auto" else float(args.focus)
        viewer.model.frame_lens()
        # --aperture and --blur hold at the start camera's reference width
        lens = request.lens(replace(viewer.model.camera(), ref_width=start.ref_width), settings.focus, viewer.model.depth_span)
        if request.aperture is not None:
            viewer.model.start_aperture = settings.aperture = lens.aperture
        elif request.blur is not None:  # R, U and N resolve it again on their view's depths
            viewer.model.start_blur, settings.aperture = request.blur, lens.aperture
        elif settings.physical:
            settings.aperture = lens.aperture  # where the slider starts if the physical lens is turned off
        if args.stats == "joint" and settings.operator().adaptive:
            viewer.model.lock_joint_stats()
        runner = ScriptRunner(actions, str(args.script)) if actions is not None else None
        while not window.should_close:
            window.poll(None if runner or viewer.model.busy or viewer.fly_mode else 1 / 30)
            if runner:
                runner.step(viewer)
            viewer.frame()
    finally:
        viewer.close()
        window.destroy()
    return 0
