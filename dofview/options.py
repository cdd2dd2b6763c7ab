"""Command-line options shared by ``render``, ``view``, ``bench`` and ``train``, and the objects
built from them (scene, camera, lens, tone mapping, splatting settings).

Each value parser rejects a bad value with a one-line argparse error.
"""

from __future__ import annotations

import argparse
import math
import shlex
import sys
from dataclasses import replace
from pathlib import Path
from typing import Callable

from dofview.camera import REFERENCE_WIDTH, Camera, look_at
from dofview.errors import DofviewError
from dofview.frame import CUT_MODES, KERNELS, OPACITY_NORMS, RenderSettings
from dofview.framing import UP_AXES, UpGuess, count_in_view, guess_up, overview_camera
from dofview.io.cameras import load_cameras_json, select_camera
from dofview.io.spz import AXES as SPZ_AXES
from dofview.lens import BlurSpec, Lens, PhysicalLens, exposure_from_shutter
from dofview.rendering import AUTO_ORDER, BACKENDS
from dofview.scene import COLOUR_SPACES, GaussianScene
from dofview.tonemap import Tonemap, default_operator

RASTERS: tuple[str, ...] = ("auto", *BACKENDS)


# ---- value parsers: each rejects a bad value with a one-line argparse error ---------------------
def number(lo: float | None = None, hi: float | None = None, lo_open: bool = False, hi_open: bool = True,
            integer: bool = False, what: str = "value") -> Callable[[str], float]:
    def parse(text: str):
        try:
            v = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what} must be a {'whole number' if integer else 'number'}, got {text!r}")
        if isinstance(v, float) and not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{what} must be finite, got {text!r}")
        if lo is not None and (v < lo or (lo_open and v == lo)):
            raise argparse.ArgumentTypeError(f"{what} must be {'>' if lo_open else '≥'} {lo:g}, got {text}")
        if hi is not None and (v > hi or (hi_open and v == hi)):
            raise argparse.ArgumentTypeError(f"{what} must be {'<' if hi_open else '≤'} {hi:g}, got {text}")
        return v
    return parse


def vec3(text: str) -> tuple[float, float, float]:
    try:
        v = tuple(float(p) for p in text.split(","))
    except ValueError:
        v = ()
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise argparse.ArgumentTypeError(f"expected three finite numbers x,y,z, got {text!r}")
    return v  # type: ignore[return-value]


def colour(text: str) -> tuple[float, float, float]:
    v = vec3(text)
    if not all(0.0 <= x <= 1.0 for x in v):
        raise argparse.ArgumentTypeError(f"colour components must be in [0, 1], got {text!r}")
    return v


def focus_value(text: str) -> float | str:
    if text == "auto":
        return text
    if text in ("inf", "infinity"):
        return math.inf
    return number(0.0, None, lo_open=True, what="focus distance")(text)


def up_value(text: str) -> str:
    """An axis label such as -y, or a direction x,y,z (kept as text: :class:`UpGuess` reads it)."""
    if text in UP_AXES:
        return text
    try:
        v = vec3(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"up must be one of {', '.join(UP_AXES)} or a direction x,y,z, "
                                         f"got {text!r}") from None
    if not any(v):
        raise argparse.ArgumentTypeError(f"up must not be the zero vector, got {text!r}")
    return ",".join(f"{c:.17g}" for c in v)


def focus_or_pull(text: str) -> float | str | tuple:
    """A focus value, or ``A:B`` (each a value or auto): a focus pull from A to B over a sequence."""
    near, sep, far = text.partition(":")
    if not sep:
        return focus_value(text)
    if not near or not far:
        raise argparse.ArgumentTypeError(f"a focus pull is written A:B, e.g. 2:8, got {text!r}")
    return focus_value(near), focus_value(far)


def blur_value(text: str) -> BlurSpec:
    """``--blur``: ``R`` (pixels at the camera's reference width), ``R%`` (of the image width), each
    optionally ``@DEPTH`` (scene units or inf: the blur of that depth; default the largest in view)."""
    radius, sep, depth = text.partition("@")
    percent = radius.endswith("%")
    what = "--blur: a blur radius such as 4 (pixels), 0.5% (of the image width) or 4@inf (at a depth)"
    r = number(0.0, None, hi_open=False, what="blur radius")(radius[:-1] if percent else radius)
    if not sep:
        return BlurSpec(r, percent)
    if not depth:
        raise argparse.ArgumentTypeError(f"{what}; got {text!r}")
    d = math.inf if depth in ("inf", "infinity") else number(0.0, None, lo_open=True, what="blur depth")(depth)
    return BlurSpec(r, percent, d)


def tau_value(text: str) -> float:
    """τ as a number or a fraction such as 2/255."""
    num, _, den = text.partition("/")
    try:
        v = float(num) / float(den) if den else float(num)
    except (ValueError, ZeroDivisionError):
        raise argparse.ArgumentTypeError(f"tau must be a number such as 0.008 or 2/255, got {text!r}")
    if not (0.0 <= v < 1.0):
        raise argparse.ArgumentTypeError(f"tau must be in [0, 1), got {text}")
    return v


# ---- shared option groups -----------------------------------------------------------------------
def add_scene_args(p: argparse.ArgumentParser) -> None:
    from dofview.io import READERS

    p.add_argument("scene", type=Path, help=f"trained 3DGS scene ({', '.join(READERS)}; a SOG folder), or a run "
                                            "folder holding point_cloud/iteration_N/point_cloud.ply and cameras.json")
    p.add_argument("--iteration", type=number(0, None, integer=True, what="iteration"),
                   help="run folder: the training iteration to open (default the highest)")
    p.add_argument("--colour-space", "--color-space", choices=COLOUR_SPACES,
                   help="override the scene's colour space (default: from the file; standard 3DGS files are srgb)")
    p.add_argument("--spz-axes", choices=SPZ_AXES,
                   help="the axes a .spz file's data is in: rub = the SPZ spec (default, or what the file records), "
                        "rdf = PLY axes as stored (files written by splat-transform)")


def add_view_args(p: argparse.ArgumentParser, default_size: tuple[int, int] = (800, 600)) -> None:
    g = p.add_argument_group("camera")
    g.add_argument("--width", type=number(1, None, integer=True, what="width"), help=f"image width (default {default_size[0]}, or the camera's)")
    g.add_argument("--height", type=number(1, None, integer=True, what="height"), help=f"image height (default {default_size[1]}, or the camera's)")
    g.add_argument("--cameras", type=Path, help="Inria cameras.json")
    g.add_argument("--view", default="0", help="camera index or image name in --cameras (default 0)")
    g.add_argument("--eye", type=vec3, help="camera position x,y,z (scene units)")
    g.add_argument("--target", type=vec3, help="point looked at x,y,z (scene units)")
    g.add_argument("--fov", type=number(0, 180, lo_open=True, what="field of view"), help="horizontal field of view, degrees (default 50)")
    g.add_argument("--near", type=number(0, None, lo_open=True, what="near plane"), default=0.01, help="near plane, scene units (default 0.01)")
    g.add_argument("--up", type=up_value, help=f"world up: {'|'.join(UP_AXES)} or a direction x,y,z "
                                               "(default: guessed from the scene's ground; with cameras, theirs; with --eye/--target, -y)")
    p.add_argument("--raster", choices=RASTERS, default="auto",
                   help="renderer backend: quad (instanced quads, the reference), compute (tile rasteriser in "
                        "compute shaders, OpenGL 4.3), auto (default: the first of "
                        f"{', '.join(AUTO_ORDER)} that runs here, in the order measured fastest)")


def add_lens_args(p: argparse.ArgumentParser, focus_pull: bool = False) -> None:
    """``focus_pull``: --focus also takes A:B (a sequence's focus pull)."""
    g = p.add_argument_group("lens")
    g.add_argument("--focus", type=focus_or_pull if focus_pull else focus_value, default="auto",
                   help="focus distance (camera depth, scene units), 'inf', or 'auto' = median depth under the image "
                        "centre (default)" + ("; A:B pulls focus from A to B over --frames" if focus_pull else ""))
    g.add_argument("--aperture", type=number(0, None, hi_open=False, what="aperture"),
                   help="aperture strength A, px·scene unit, at the camera's reference width: CoC radius "
                        "R = A/2·|1/z − 1/d_f| there (default 0 = pinhole). The reference width is a cameras.json "
                        f"view's own width, else {REFERENCE_WIDTH} px (--eye/--target, automatic framing); at "
                        "another --width A scales with it, so the picture is the same, scaled")
    g.add_argument("--blur", type=blur_value, metavar="R[%][@DEPTH]",
                   help="depth of field by the blur it makes: the largest blur in view (2nd–98th percentile depths "
                        "of a pinhole pass) has radius R px at the reference width, or R%% of the image width; "
                        "R@DEPTH gives that blur to camera depth DEPTH (e.g. 6@inf: the far background)")
    g.add_argument("--fnumber", type=number(0, None, lo_open=True, what="f-number"), help="physical lens: f-number N (with --focal-mm)")
    g.add_argument("--focal-mm", type=number(0, None, lo_open=True, what="focal length"), help="physical lens: focal length in mm")
    g.add_argument("--sensor-mm", type=number(0, None, lo_open=True, what="sensor width"), default=36.0, help="physical lens: sensor width in mm (default 36)")
    g.add_argument("--units-per-metre", "--units-per-meter", type=number(0, None, lo_open=True, what="units per metre"), default=1.0, help="physical lens: scene units per metre (default 1)")
    g = p.add_argument_group("image")
    g.add_argument("--exposure", type=number(-60, 60, hi_open=False, what="exposure"), default=0.0, help="exposure in EV stops, multiplier 2^EV (default 0)")
    g.add_argument("--shutter", type=number(0, None, lo_open=True, what="shutter time"), help="exposure time t in seconds: with --fnumber N, exposure log2(t/N²) EV (the factor t/N² of Eq. 7), instead of --exposure")
    g.add_argument("--gamma", type=number(0, None, lo_open=True, what="gamma"), default=2.2, help="display gamma (default 2.2)")
    g.add_argument("--background", type=colour, default=(0.0, 0.0, 0.0), help="display background r,g,b in [0,1] (PNG only; default black)")
    add_tonemap_args(g)
    g = p.add_argument_group("splatting")
    g.add_argument("--tau", type=tau_value, default=RenderSettings.tau, help=f"minimum alpha τ in [0, 1), e.g. 2/255 (default {RenderSettings.tau * 255:g}/255)")
    g.add_argument("--k", type=number(0, None, hi_open=False, what="k"), default=RenderSettings.k, help=f"aperture covariance scale k (default {RenderSettings.k:g})")
    g.add_argument("--opacity-norm", choices=OPACITY_NORMS, default=RenderSettings.opacity_norm, help=f"opacity normalisation under blur (default {RenderSettings.opacity_norm})")
    g.add_argument("--cut", choices=CUT_MODES, default=RenderSettings.cut, help=f"how τ cuts a splat: drop the light below τ, or conserve each splat's mass (default {RenderSettings.cut})")
    g.add_argument("--blend-linear", action="store_true", help="decode splat colours to linear light before blending (sRGB scenes)")
    g.add_argument("--kernel", choices=KERNELS, default=RenderSettings.kernel, help=f"aperture kernel: a Gaussian, or the splat spread over the CoC disk (default {RenderSettings.kernel})")


# ---- building objects from arguments ------------------------------------------------------------
def load_scene_arg(args: argparse.Namespace, progress: bool = True) -> GaussianScene:
    from dofview.io import load_scene
    from dofview.io.runfolder import find_run

    run = find_run(args.scene, getattr(args, "iteration", None))
    args.scene = run.scene
    explicit = getattr(args, "cameras", None) is not None or getattr(args, "eye", None) or getattr(args, "target", None)
    if run.cameras is not None and hasattr(args, "cameras") and not explicit:  # --cameras or --eye/--target win
        args.cameras = run.cameras
        note(args, run.describe(len(load_cameras_json(run.cameras))))
    elif run.root is not None:
        note(args, run.describe())
    scene = load_scene(args.scene, progress=progress, spz_axes=getattr(args, "spz_axes", None),
                       report=lambda line: print(line, file=sys.stderr))
    if args.colour_space:
        scene.colour_space = args.colour_space
    return scene


def camera_from_args(args: argparse.Namespace, scene: GaussianScene, default_size=(800, 600)) -> Camera:
    if args.cameras and (args.eye or args.target):
        raise DofviewError("use either --cameras/--view or --eye/--target, not both")
    physical_fov = None
    if getattr(args, "focal_mm", None) and args.fov is None:
        physical_fov = math.degrees(2 * math.atan(args.sensor_mm / (2 * args.focal_mm)))
    if args.cameras:
        cam = select_camera(load_cameras_json(args.cameras), args.view, str(args.cameras))
        w = args.width or (round(cam.width * args.height / cam.height) if args.height else cam.width)
        h = args.height or (round(cam.height * args.width / cam.width) if args.width else cam.height)
        what = f"camera {cam.name or args.view!r} of {Path(args.cameras).absolute()}"
        return _check_seen(args, scene, cam.resized(w, h), what)
    dw, dh = default_size
    w = args.width or (round(dw * args.height / dh) if args.height else dw)
    h = args.height or (round(dh * args.width / dw) if args.width else dh)
    fov = args.fov or physical_fov or 50.0
    if args.eye or args.target:
        if not (args.eye and args.target):
            raise DofviewError("--eye and --target go together")
        cam = look_at(args.eye, args.target, w, h, fov, UpGuess(args.up).vector if args.up else (0.0, -1.0, 0.0))
        _check_seen(args, scene, cam, "the camera of --eye/--target")
    else:
        cam = overview_camera(scene, w, h, fov, up_from_args(args, scene).vector)
    return replace(cam, ref_width=REFERENCE_WIDTH)  # no size of its own: --aperture holds at the default width


def _check_seen(args: argparse.Namespace, scene: GaussianScene, cam: Camera, what: str) -> Camera:
    """``cam``, the camera the user chose (``what``, in words), when it sees some of the scene. One that
    sees none of it is refused where ``--focus auto`` would have nothing to focus on, else noted: the
    image it makes is empty, and the user is told why rather than given a black picture.

    Raises:
        DofviewError: ``cam`` sees no Gaussian and the focus is automatic.
    """
    if count_in_view(scene, cam, getattr(args, "near", 0.01)) > 0:
        return cam
    line = f"{what} sees none of the {scene.count:,} Gaussians of {args.scene}"
    focus = getattr(args, "focus", None)
    if "auto" in (focus if isinstance(focus, tuple) else (focus,)):
        raise DofviewError(f"{line}: nothing in view to focus on; choose another view (--view, --eye/--target), "
                           "or give --focus to render the empty view")
    note(args, f"dofview: warning: {line}: the image is empty")
    return cam


def up_from_args(args: argparse.Namespace, scene: GaussianScene) -> UpGuess:
    """World up for a scene without cameras: ``--up``, else guessed (and noted, once)."""
    if getattr(args, "up_guess", None) is None:
        if getattr(args, "up", None):
            args.up_guess = UpGuess(args.up, "--up")
        else:
            args.up_guess = guess_up(scene)
            note(args, f"up axis {args.up_guess.label} (guessed: {args.up_guess.reason}; --up overrides)")
    return args.up_guess


def note(args: argparse.Namespace, line: str) -> None:
    """Keep a line about what was found or guessed (run folder, cameras, up axis) for :func:`say_notes`."""
    args.notes = [*getattr(args, "notes", []), line]


def say_notes(args: argparse.Namespace) -> None:
    """Print the noted lines to stderr, once: commands call it when their work is under way, so that
    a mistake found earlier stays a one-line error."""
    for line in getattr(args, "notes", []):
        print(line, file=sys.stderr)
    args.notes = []


def needs_depths(args: argparse.Namespace) -> bool:
    """Whether the lens options need the depth range in view (``--blur R`` without ``@DEPTH``)."""
    blur = getattr(args, "blur", None)
    return blur is not None and blur.depth is None


def lens_from_args(args: argparse.Namespace, camera: Camera, focus: float,
                   span: tuple[float, float] | None = None) -> Lens:
    """The lens the options ask for on ``camera`` at ``focus`` (scene units): ``--aperture A``
    scaled from the camera's reference width to its width, ``--blur`` resolved on ``span`` (the
    (near, far) depths in view, scene units, from :func:`dofview.rendering.focus.depth_range`), or
    the physical lens through the camera's f_x (which scales with the width by itself)."""
    physical = args.fnumber is not None or args.focal_mm is not None
    blur = getattr(args, "blur", None)
    if sum((physical, args.aperture is not None, blur is not None)) > 1:
        raise DofviewError("give the aperture one way: --aperture A, --blur R or --fnumber/--focal-mm")
    if physical:
        if args.fnumber is None or args.focal_mm is None:
            raise DofviewError("a physical lens needs both --fnumber and --focal-mm")
        return PhysicalLens(args.focal_mm, args.fnumber, args.sensor_mm, args.units_per_metre).lens(camera.fx, focus)
    if blur is not None:
        return Lens(focus=focus, aperture=blur.aperture(camera.width, camera.ref_width, focus, span))
    return Lens(focus=focus, aperture=camera.scaled_aperture(args.aperture or 0.0))


def aperture_asked(args: argparse.Namespace) -> str:
    """The lens options as given, for the EXR header (``--blur 1%``, ``--aperture 60``, …)."""
    blur = getattr(args, "blur", None)
    if blur is not None:
        return f"--blur {blur}"
    if args.fnumber is not None or args.focal_mm is not None:
        return f"--fnumber {args.fnumber:g} --focal-mm {args.focal_mm:g}"
    return f"--aperture {args.aperture or 0.0:g}"


def add_tonemap_args(g) -> None:
    """--tonemap NAME (choices: dofview.tonemap.OPERATORS), --stats, and one flag per operator
    parameter, --NAME-PARAM (e.g. --reinhard05-b 0.5), from the operators' dataclass fields."""
    from dataclasses import fields

    from dofview.tonemap import AUTO, LINEAR_DEFAULT, OPERATORS

    g.add_argument("--tonemap", choices=[AUTO, *OPERATORS], default=AUTO,
                   help="tone-mapping operator for the PNG and the screen; the EXR stays linear (default auto: "
                        f"clip = Eq. 7 for an sRGB scene, {LINEAR_DEFAULT} for a linear HDR one)")
    g.add_argument("--stats", choices=("frame", "joint"), default="frame",
                   help="statistics of adaptive operators: this frame's, or pooled over all views of --cameras (default frame)")
    for name, cls in OPERATORS.items():
        for f in fields(cls):
            g.add_argument(f"--{name}-{f.name.replace('_', '-')}", dest=f"tm_{name}_{f.name}",
                           type=number(integer=f.type == "int", what=f"{name} {f.name}"), metavar="V",
                           help=f"{name}: {f.name} (default {f.default:g}; see dofview.tonemap.{cls.__module__.rsplit('.', 1)[1]})")


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
    cls = OPERATORS[name]
    return cls(**{f.name: getattr(args, f"tm_{name}_{f.name}") for f in fields(cls)
                  if getattr(args, f"tm_{name}_{f.name}", None) is not None})


def tonemap_from_args(args: argparse.Namespace, colour_space: str = "srgb") -> Tonemap:
    if args.shutter is not None:
        if args.fnumber is None:
            raise DofviewError("--shutter needs --fnumber (exposure = t/N²)")
        exposure = math.log2(exposure_from_shutter(args.shutter, args.fnumber))
    else:
        exposure = args.exposure
    return Tonemap(exposure=exposure, gamma=args.gamma, background=args.background,
                   operator=operator_from_args(args, colour_space))


def stats_from_args(args: argparse.Namespace, renderer, tm: Tonemap, settings: RenderSettings):
    """The tone-mapping statistics ``--stats`` asks for: pooled over every training view of
    ``--cameras`` (``joint``, for sequences that must not adapt), or None for each frame's own."""
    if args.stats != "joint" or not tm.operator.adaptive:
        return None
    if args.cameras is None:
        raise DofviewError("--stats joint pools the views of --cameras: give --cameras")
    from dofview.api import joint_stats

    return joint_stats(renderer, load_cameras_json(args.cameras), tm.operator, settings)


def settings_from_args(args: argparse.Namespace) -> RenderSettings:
    return RenderSettings(tau=args.tau, k=args.k, opacity_norm=args.opacity_norm,
                          blend_linear=args.blend_linear, near=args.near, cut=args.cut,
                          kernel=args.kernel)


def render_command_line(scene_path: str, camera: Camera, lens: Lens, tm: Tonemap, settings: RenderSettings,
                        colour_space: str, out: str = "out.exr") -> str:
    """A ``dofview render`` line that reproduces a view (used by the viewer's "copy as command").

    ``lens.aperture`` is the strength on ``camera`` as drawn; the line gives it at the reference
    width of an --eye/--target camera, so the same line with another --width gives the same
    picture, scaled."""
    eye = camera.centre
    target = eye + camera.forward * (lens.focus if math.isfinite(lens.focus) else 1.0)
    fov = camera.fov_x_deg
    parts = ["dofview", "render", shlex.quote(scene_path), "-o", shlex.quote(out),
             "--width", str(camera.width), "--height", str(camera.height),
             # "--eye=…" form: argparse would take a value like "-1.5,0,2" for an option
             "--eye=" + ",".join(f"{v:.6g}" for v in eye), "--target=" + ",".join(f"{v:.6g}" for v in target),
             "--up=" + ",".join(f"{v:.6g}" for v in -camera.R[1]),  # image-up: keeps the camera's roll
             "--fov", f"{fov:.6g}", "--focus", f"{lens.focus:.6g}",
             "--aperture", f"{lens.aperture * REFERENCE_WIDTH / camera.width:.6g}",
             "--exposure", f"{tm.exposure:.6g}", "--gamma", f"{tm.gamma:.6g}",
             "--tau", f"{settings.tau:.6g}", "--k", f"{settings.k:.6g}", "--opacity-norm", settings.opacity_norm,
             "--cut", settings.cut, "--kernel", settings.kernel,
             "--colour-space", colour_space]
    if any(tm.background):
        parts += ["--background", ",".join(f"{c:.4g}" for c in tm.background)]
    if tm.operator.name != default_operator(colour_space) or tm.operator.params():
        parts += ["--tonemap", tm.operator.name]
        parts += [f"--{tm.operator.name}-{k.replace('_', '-')}={v:.6g}" for k, v in tm.operator.params().items()]
    if settings.blend_linear:
        parts.append("--blend-linear")
    return " ".join(parts)


