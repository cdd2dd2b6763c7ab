"""What the shared command-line options ask for, as core objects: the scene opened (and what was
found beside it), the camera, the lens request, the tone mapping and the splatting settings.

Used by ``dofview render`` (:mod:`dofview.cli.job`), the viewer and the bench, which parse the
options of :mod:`dofview.options`. Nothing here changes the parsed arguments: what was found or
guessed (a run folder's cameras, the up axis) is returned, with the lines to tell the user.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path

from dofview.camera import REFERENCE_WIDTH, Camera, look_at
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.framing import UpGuess, count_in_view, guess_up, overview_camera
from dofview.io.cameras import load_cameras_json, select_camera
from dofview.io.lod import LodSet, is_lod_set, open_lod
from dofview.lens import LensRequest, shutter_ev
from dofview.scene import GaussianScene
from dofview.tonemap import Tonemap, operator_from_dict


@dataclass
class OpenedScene:
    """A scene opened from the command line.

    Attributes:
        scene: the Gaussians (colour space overridden by ``--colour-space``).
        path: the scene file read (a run folder's point_cloud.ply, or the path given).
        cameras: the cameras.json to use: ``--cameras``, else a run folder's when neither
            --cameras nor --eye/--target was given; None without one.
        notes: lines about what was found or guessed, for :meth:`say_notes`.
        up: the world up for views without cameras, once :func:`up_from_args` has chosen it.
        lod_set: the streamed LOD set ``scene`` is a level of (:mod:`dofview.io.lod`), or None.
    """

    scene: GaussianScene
    path: Path
    cameras: Path | None
    notes: list[str] = field(default_factory=list)
    up: UpGuess | None = None
    lod_set: LodSet | None = None

    def say_notes(self) -> None:
        """Print the noted lines to stderr, once: commands call it when their work is under way,
        so that a mistake found earlier stays a one-line error."""
        for line in self.notes:
            print(line, file=sys.stderr)
        self.notes.clear()


def open_scene(args: argparse.Namespace, progress: bool = True, cameras: Path | None = None) -> OpenedScene:
    """The scene of ``args.scene`` (a file or a run folder, ``--iteration``), with its colour
    space from ``--colour-space`` and the cameras to use (``cameras`` when given: a default the
    caller found, such as the bench's NAME_cameras.json; ``--cameras`` and --eye/--target win)."""
    from dofview.io import load_scene
    from dofview.io.runfolder import find_run

    run = find_run(args.scene, getattr(args, "iteration", None))
    given = getattr(args, "cameras", None)
    explicit = given is not None or getattr(args, "eye", None) or getattr(args, "target", None)
    notes = []
    found = run.cameras if run.cameras is not None and hasattr(args, "cameras") and not explicit else None
    if found is not None:
        notes.append(run.describe(len(load_cameras_json(found))))
    elif run.root is not None:
        notes.append(run.describe())
    lod_set = open_lod(run.scene) if is_lod_set(run.scene) else None  # kept: the viewer streams from it
    _check_format_options(args, run.scene, lod_set is not None)
    scene = load_scene(run.scene, progress=progress, spz_axes=getattr(args, "spz_axes", None),
                       lod=getattr(args, "lod", None), budget=getattr(args, "budget", None), lod_set=lod_set,
                       report=lambda line: print(line, file=sys.stderr))
    if getattr(args, "colour_space", None):
        scene.colour_space = args.colour_space
    use = given if given is not None else found if found is not None else None if explicit else cameras
    return OpenedScene(scene, run.scene, use, notes, lod_set=lod_set)


def _check_format_options(args: argparse.Namespace, path: Path, lod: bool) -> None:
    """Refuse a reader's option given for a file that reader does not read: it would be dropped
    without a word (a user who asks for ``--lod 2`` of a .ply expects a coarser scene)."""
    for option, name in (("--lod", "lod"), ("--budget", "budget")):
        if not lod and getattr(args, name, None) is not None:
            raise DofviewError(f"{path}: {option} is for streamed LOD sets (lod-meta.json); "
                               "this scene is not one")
    if getattr(args, "spz_axes", None) is not None and path.suffix.lower() != ".spz":
        raise DofviewError(f"{path}: --spz-axes is for .spz files")


def camera_from_args(args: argparse.Namespace, opened: OpenedScene, default_size: tuple[int, int] = (800, 600),
                     view: str | None = None) -> Camera:
    """The camera the options give: view ``view`` (default ``--view``) of the cameras file at
    --width/--height (missing one: the aspect kept), --eye/--target, or the scene framed from its
    up axis, at ``default_size`` (width, height) when no size is given.

    Raises:
        DofviewError: both --cameras and --eye/--target, half of --eye/--target, or a chosen view
            that sees nothing while the focus is automatic.
    """
    if opened.cameras and (args.eye or args.target):
        raise DofviewError("use either --cameras/--view or --eye/--target, not both")
    physical_fov = None
    if getattr(args, "focal_mm", None) and args.fov is None:
        physical_fov = math.degrees(2 * math.atan(args.sensor_mm / (2 * args.focal_mm)))
    if opened.cameras:
        if getattr(args, "fov", None) is not None:
            raise DofviewError(f"{opened.cameras}: its views have their own field of view; --fov is for views "
                               "dofview makes (--eye/--target, or none)")
        view = args.view if view is None else view
        cam = select_camera(load_cameras_json(opened.cameras), view, str(opened.cameras))
        w = args.width or (round(cam.width * args.height / cam.height) if args.height else cam.width)
        h = args.height or (round(cam.height * args.width / cam.width) if args.width else cam.height)
        what = f"camera {cam.name or view!r} of {Path(opened.cameras).absolute()}"
        return _check_seen(args, opened, cam.resized(w, h), what)
    if view is None and getattr(args, "view", "0") != "0":
        raise DofviewError(f"--view picks a view of --cameras (or of a run folder's cameras.json); "
                           f"{opened.path} has none")
    dw, dh = default_size
    w = args.width or (round(dw * args.height / dh) if args.height else dw)
    h = args.height or (round(dh * args.width / dw) if args.width else dh)
    fov = args.fov or physical_fov or 50.0
    if args.eye or args.target:
        if not (args.eye and args.target):
            raise DofviewError("--eye and --target go together")
        cam = look_at(args.eye, args.target, w, h, fov, UpGuess(args.up).vector if args.up else (0.0, -1.0, 0.0))
        _check_seen(args, opened, cam, "the camera of --eye/--target")
    else:
        cam = overview_camera(opened.scene, w, h, fov, up_from_args(args, opened).vector)
    return replace(cam, ref_width=REFERENCE_WIDTH)  # no size of its own: --aperture holds at the default width


def _check_seen(args: argparse.Namespace, opened: OpenedScene, cam: Camera, what: str) -> Camera:
    """``cam``, the camera the user chose (``what``, in words), when it sees some of the scene. One that
    sees none of it is refused where ``--focus auto`` would have nothing to focus on, else noted: the
    image it makes is empty, and the user is told why rather than given a black picture.

    Raises:
        DofviewError: ``cam`` sees no Gaussian and the focus is automatic.
    """
    if count_in_view(opened.scene, cam, getattr(args, "near", 0.01)) > 0:
        return cam
    line = f"{what} sees none of the {opened.scene.count:,} Gaussians of {opened.path}"
    focus = getattr(args, "focus", None)
    if "auto" in (focus if isinstance(focus, tuple) else (focus,)):
        raise DofviewError(f"{line}: nothing in view to focus on; choose another view (--view, --eye/--target), "
                           "or give --focus to render the empty view")
    opened.notes.append(f"dofview: warning: {line}: the image is empty")
    return cam


def up_from_args(args: argparse.Namespace, opened: OpenedScene) -> UpGuess:
    """World up for a scene without cameras: ``--up``, else guessed (and noted, once)."""
    if opened.up is None:
        if getattr(args, "up", None):
            opened.up = UpGuess(args.up, "--up")
        else:
            opened.up = guess_up(opened.scene)
            opened.notes.append(f"up axis {opened.up.label} (guessed: {opened.up.reason}; --up overrides)")
    return opened.up


def lens_request_from_args(args: argparse.Namespace) -> LensRequest:
    """The lens options as a :class:`LensRequest` (refuses more than one way, or half a physical lens)."""
    return LensRequest(aperture=args.aperture, blur=getattr(args, "blur", None), fnumber=args.fnumber,
                       focal_mm=args.focal_mm, sensor_mm=args.sensor_mm, units_per_metre=args.units_per_metre)


def operator_from_args(args: argparse.Namespace, colour_space: str = "srgb"):
    """The --tonemap operator with its --NAME-PARAM flags (``auto``: the scene's default for
    ``colour_space``); a flag for another operator is an error."""
    from dataclasses import fields

    from dofview.tonemap import AUTO, OPERATORS, default_operator

    name = getattr(args, "tonemap", AUTO)
    name = default_operator(colour_space) if name == AUTO else name
    for other, cls in OPERATORS.items():
        given = [f.name for f in fields(cls) if getattr(args, f"tm_{other}_{f.name}", None) is not None]
        if other != name and given:
            raise DofviewError(f"--{other}-{given[0].replace('_', '-')} needs --tonemap {other}")
    params = {f.name: getattr(args, f"tm_{name}_{f.name}") for f in fields(OPERATORS[name])
              if getattr(args, f"tm_{name}_{f.name}", None) is not None}
    return operator_from_dict({"operator": name, **params})


def tonemap_from_args(args: argparse.Namespace, colour_space: str = "srgb") -> Tonemap:
    """--exposure (or --shutter with --fnumber: log2(t/N²) EV), --gamma, --background and the operator."""
    if args.shutter is not None:
        if args.fnumber is None:
            raise DofviewError("--shutter needs --fnumber (exposure = t/N²)")
        exposure = shutter_ev(args.shutter, args.fnumber)
    else:
        exposure = args.exposure
    operator = operator_from_args(args, colour_space)
    operator.require()  # --tonemap aces without OpenColorIO: said before anything is rendered
    return Tonemap(exposure=exposure, gamma=args.gamma, background=args.background, operator=operator)


def settings_from_args(args: argparse.Namespace) -> RenderSettings:
    """The splatting options (--tau, --k, --opacity-norm, --cut, --kernel, --near, --blend-linear,
    --dof, --blades, --blade-rotation)."""
    if (args.blades or args.blade_rotation) and args.dof != "sliced":
        raise DofviewError("--blades and --blade-rotation shape the aperture of --dof sliced; --dof splat has none")
    return RenderSettings(tau=args.tau, k=args.k, opacity_norm=args.opacity_norm,
                          blend_linear=args.blend_linear, near=args.near, cut=args.cut, kernel=args.kernel,
                          dof=args.dof, blades=int(args.blades), blade_rotation=args.blade_rotation)
