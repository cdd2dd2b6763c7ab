"""The ``dofview`` command line: ``render`` here; ``view``, ``bench`` and ``train`` in their modules.

User mistakes (bad files, bad values) print one line ``dofview: error: …`` and exit 2, with no
traceback; outputs are written whole or not at all.
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
import warnings
from pathlib import Path
from typing import Callable, Sequence

from . import __version__
from .camera import Camera, framing_camera, load_cameras_json, look_at, select_camera
from .errors import DofviewError, DofviewWarning
from .frame import OPACITY_NORMS, RenderSettings
from .lens import Lens, PhysicalLens, exposure_from_ev, exposure_from_shutter
from .scene import COLOUR_SPACES, GaussianScene
from .tonemap import Tonemap


# ---- value parsers: each rejects a bad value with a one-line argparse error ---------------------
def _number(lo: float | None = None, hi: float | None = None, lo_open: bool = False, hi_open: bool = True,
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


def _vec3(text: str) -> tuple[float, float, float]:
    try:
        v = tuple(float(p) for p in text.split(","))
    except ValueError:
        v = ()
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise argparse.ArgumentTypeError(f"expected three finite numbers x,y,z, got {text!r}")
    return v  # type: ignore[return-value]


def _colour(text: str) -> tuple[float, float, float]:
    v = _vec3(text)
    if not all(0.0 <= x <= 1.0 for x in v):
        raise argparse.ArgumentTypeError(f"colour components must be in [0, 1], got {text!r}")
    return v


def _focus(text: str) -> float | str:
    if text == "auto":
        return text
    if text in ("inf", "infinity"):
        return math.inf
    return _number(0.0, None, lo_open=True, what="focus distance")(text)


def _tau(text: str) -> float:
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
    p.add_argument("scene", type=Path, help="trained 3DGS scene (.ply or .splat)")
    p.add_argument("--colour-space", "--color-space", choices=COLOUR_SPACES,
                   help="override the scene's colour space (default: from the file; standard 3DGS files are srgb)")


def add_view_args(p: argparse.ArgumentParser, default_size: tuple[int, int] = (800, 600)) -> None:
    g = p.add_argument_group("camera")
    g.add_argument("--width", type=_number(1, None, integer=True, what="width"), help=f"image width (default {default_size[0]}, or the camera's)")
    g.add_argument("--height", type=_number(1, None, integer=True, what="height"), help=f"image height (default {default_size[1]}, or the camera's)")
    g.add_argument("--cameras", type=Path, help="Inria cameras.json")
    g.add_argument("--view", default="0", help="camera index or image name in --cameras (default 0)")
    g.add_argument("--eye", type=_vec3, help="camera position x,y,z (scene units)")
    g.add_argument("--target", type=_vec3, help="point looked at x,y,z (scene units)")
    g.add_argument("--fov", type=_number(0, 180, lo_open=True, what="field of view"), help="horizontal field of view, degrees (default 50)")
    g.add_argument("--near", type=_number(0, None, lo_open=True, what="near plane"), default=0.01, help="near plane, scene units (default 0.01)")


def add_lens_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("lens")
    g.add_argument("--focus", type=_focus, default="auto", help="focus distance (camera depth, scene units), 'inf', or 'auto' = median depth under the image centre (default)")
    g.add_argument("--aperture", type=_number(0, None, hi_open=False, what="aperture"), help="aperture strength A, px·scene unit: CoC radius R = A/2·|1/z − 1/d_f| (default 0 = pinhole)")
    g.add_argument("--fnumber", type=_number(0, None, lo_open=True, what="f-number"), help="physical lens: f-number N (with --focal-mm)")
    g.add_argument("--focal-mm", type=_number(0, None, lo_open=True, what="focal length"), help="physical lens: focal length in mm")
    g.add_argument("--sensor-mm", type=_number(0, None, lo_open=True, what="sensor width"), default=36.0, help="physical lens: sensor width in mm (default 36)")
    g.add_argument("--units-per-metre", "--units-per-meter", type=_number(0, None, lo_open=True, what="units per metre"), default=1.0, help="physical lens: scene units per metre (default 1)")
    g = p.add_argument_group("image")
    g.add_argument("--exposure", type=_number(-60, 60, hi_open=False, what="exposure"), default=0.0, help="exposure in EV stops, multiplier 2^EV (default 0)")
    g.add_argument("--shutter", type=_number(0, None, lo_open=True, what="shutter time"), help="exposure time t in seconds: exposure = t/N² with --fnumber (Eq. 7), instead of --exposure")
    g.add_argument("--gamma", type=_number(0, None, lo_open=True, what="gamma"), default=2.2, help="display gamma (default 2.2)")
    g.add_argument("--background", type=_colour, default=(0.0, 0.0, 0.0), help="display background r,g,b in [0,1] (PNG only; default black)")
    g = p.add_argument_group("splatting")
    g.add_argument("--tau", type=_tau, default=RenderSettings.tau, help=f"minimum alpha τ in [0, 1), e.g. 2/255 (default {RenderSettings.tau * 255:g}/255)")
    g.add_argument("--k", type=_number(0, None, hi_open=False, what="k"), default=RenderSettings.k, help=f"aperture covariance scale k (default {RenderSettings.k:g})")
    g.add_argument("--opacity-norm", choices=OPACITY_NORMS, default=RenderSettings.opacity_norm, help=f"opacity normalisation under blur (default {RenderSettings.opacity_norm})")
    g.add_argument("--blend-linear", action="store_true", help="decode splat colours to linear light before blending (sRGB scenes)")


# ---- building objects from arguments ------------------------------------------------------------
def load_scene_arg(args: argparse.Namespace, progress: bool = True) -> GaussianScene:
    from .scenefile import load_scene

    scene = load_scene(args.scene, progress=progress)
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
        return cam.resized(w, h)
    w, h = args.width or default_size[0], args.height or default_size[1]
    fov = args.fov or physical_fov or 50.0
    if args.eye or args.target:
        if not (args.eye and args.target):
            raise DofviewError("--eye and --target go together")
        return look_at(args.eye, args.target, w, h, fov)
    return framing_camera(scene, w, h, fov)


def lens_from_args(args: argparse.Namespace, camera: Camera, focus: float) -> Lens:
    physical = args.fnumber is not None or args.focal_mm is not None
    if physical and args.aperture is not None:
        raise DofviewError("give the aperture either as --aperture A or as --fnumber/--focal-mm, not both")
    if physical:
        if args.fnumber is None or args.focal_mm is None:
            raise DofviewError("a physical lens needs both --fnumber and --focal-mm")
        return PhysicalLens(args.focal_mm, args.fnumber, args.sensor_mm, args.units_per_metre).lens(camera.fx, focus)
    return Lens(focus=focus, aperture=args.aperture or 0.0)


def tonemap_from_args(args: argparse.Namespace) -> Tonemap:
    if args.shutter is not None:
        if args.fnumber is None:
            raise DofviewError("--shutter needs --fnumber (exposure = t/N²)")
        exposure = exposure_from_shutter(args.shutter, args.fnumber)
    else:
        exposure = exposure_from_ev(args.exposure)
    return Tonemap(exposure=exposure, gamma=args.gamma, background=args.background)


def settings_from_args(args: argparse.Namespace) -> RenderSettings:
    return RenderSettings(tau=args.tau, k=args.k, opacity_norm=args.opacity_norm,
                          blend_linear=args.blend_linear, near=args.near)


def render_command_line(scene_path: str, camera: Camera, lens: Lens, tm: Tonemap, settings: RenderSettings,
                        colour_space: str, out: str = "out.exr") -> str:
    """A ``dofview render`` line that reproduces a view (used by the viewer's "copy as command")."""
    eye = camera.centre
    target = eye + camera.forward * (lens.focus if math.isfinite(lens.focus) else 1.0)
    fov = camera.fov_x_deg
    parts = ["dofview", "render", shlex.quote(scene_path), "-o", shlex.quote(out),
             "--width", str(camera.width), "--height", str(camera.height),
             # "--eye=…" form: argparse would take a value like "-1.5,0,2" for an option
             "--eye=" + ",".join(f"{v:.6g}" for v in eye), "--target=" + ",".join(f"{v:.6g}" for v in target),
             "--fov", f"{fov:.6g}", "--focus", f"{lens.focus:.6g}", "--aperture", f"{lens.aperture:.6g}",
             "--exposure", f"{math.log2(tm.exposure):.6g}", "--gamma", f"{tm.gamma:.6g}",
             "--tau", f"{settings.tau:.6g}", "--k", f"{settings.k:.6g}", "--opacity-norm", settings.opacity_norm,
             "--colour-space", colour_space]
    if any(tm.background):
        parts += ["--background", ",".join(f"{c:.4g}" for c in tm.background)]
    if settings.blend_linear:
        parts.append("--blend-linear")
    return " ".join(parts)


def save_render(renderer, camera: Camera, lens: Lens, tm: Tonemap, settings: RenderSettings, scene_path: str,
                output: Path, png: Path | None = None, half: bool = False,
                lens_info: dict[str, float | None] | None = None) -> None:
    """Render a view and write it as ``dofview render`` does: a linear EXR (exposure applied, Z, dofview
    header) and optionally the tonemapped PNG. Shared by the CLI and the viewer's Save.

    ``lens_info`` holds the physical-lens values for the header (fnumber, focal_mm, sensor_mm,
    units_per_metre; None where not used).
    """
    from .exr import write_exr
    from .png import write_png

    frame = renderer.render(camera, lens, settings)
    header = {
        "dofview:version": __version__,
        "dofview:scene": scene_path,
        "dofview:camera": json.dumps({"width": camera.width, "height": camera.height, "fx": camera.fx, "fy": camera.fy,
                                      "cx": camera.cx, "cy": camera.cy, "R": camera.R.tolist(), "T": camera.T.tolist()}),
        "dofview:lens": json.dumps({"focus": lens.focus, "aperture": lens.aperture, **(lens_info or {})}),
        "dofview:exposure": tm.exposure,
        "dofview:gamma": tm.gamma,
        "dofview:render": json.dumps({"tau": settings.tau, "k": settings.k, "opacity_norm": settings.opacity_norm,
                                      "blend_linear": settings.blend_linear,
                                      "colour_space": renderer.scene.colour_space}),
    }
    rgba = frame.rgba.copy()
    rgba[..., :3] *= tm.exposure
    write_exr(output, rgba, frame.depth, half=half, header=header)
    if png:
        write_png(png, renderer.display_image(tm))


# ---- render ---------------------------------------------------------------------------------------
def _add_render(sub) -> None:
    p = sub.add_parser("render", help="render a scene headless to a linear HDR EXR (+ PNG)",
                       description="Render a trained 3DGS scene with depth of field to an EXR holding linear "
                                   "R, G, B, A (premultiplied) and Z (camera depth), and optionally a PNG.")
    add_scene_args(p)
    p.add_argument("-o", "--output", type=Path, required=True, help="output EXR path")
    p.add_argument("--png", type=Path, help="also write the tonemapped image as PNG")
    p.add_argument("--half", action="store_true", help="store R, G, B, A as half floats (Z stays float32)")
    add_view_args(p)
    add_lens_args(p)
    p.set_defaults(run=run_render)


def run_render(args: argparse.Namespace) -> int:
    from .renderer import Renderer

    if args.output.suffix.lower() != ".exr":
        raise DofviewError(f"{args.output}: output must be an .exr file")
    for out in (args.output, args.png):  # before the render, not after it
        if out is not None and not out.parent.is_dir():
            raise DofviewError(f"{out}: folder {out.parent} does not exist")
    settings = settings_from_args(args)
    tm = tonemap_from_args(args)
    scene = load_scene_arg(args)
    camera = camera_from_args(args, scene)
    renderer = Renderer(scene)
    focus = args.focus
    if focus == "auto":
        from .focus import auto_focus

        focus = auto_focus(renderer.render(camera, Lens(1.0, 0.0), settings))
        if focus is None:
            raise DofviewError(f"{args.scene}: nothing under the image centre to focus on; give --focus")
    lens = lens_from_args(args, camera, float(focus))
    save_render(renderer, camera, lens, tm, settings, str(args.scene), args.output, args.png, half=args.half,
                lens_info={"fnumber": args.fnumber, "focal_mm": args.focal_mm, "sensor_mm": args.sensor_mm,
                           "units_per_metre": args.units_per_metre})
    print(f"{args.output}: {camera.width}×{camera.height}, focus {lens.focus:.4g}, aperture A={lens.aperture:.4g}, "
          f"exposure ×{tm.exposure:.4g}" + (f"; {args.png}" if args.png else ""), file=sys.stderr)
    return 0


# ---- entry point -----------------------------------------------------------------------------------
COMMAND_MODULES = ("dofview.viewer.app", "dofview.bench", "dofview.train.cli")


class _Parser(argparse.ArgumentParser):
    """argparse with dofview's one-line errors (sub-commands inherit it): exit status 2, no usage dump."""

    def error(self, message: str):
        self.exit(2, f"dofview: error: {message} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="dofview", description="A camera lens for trained 3D Gaussian Splatting scenes.")
    parser.add_argument("--version", action="version", version=f"dofview {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_render(sub)
    import importlib

    for name in COMMAND_MODULES:
        try:
            mod = importlib.import_module(name)
        except ModuleNotFoundError as e:
            if e.name and (e.name == name or name.startswith(e.name + ".")):
                continue  # that command is not part of this build
            raise
        mod.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    with warnings.catch_warnings():
        python_show = warnings.showwarning

        def show(message, category, *rest, **kw) -> None:  # repaired input: one line, no source excerpt
            if issubclass(category, DofviewWarning):
                print(f"dofview: warning: {message}", file=sys.stderr)
            else:
                python_show(message, category, *rest, **kw)

        warnings.simplefilter("always", DofviewWarning)
        warnings.showwarning = show
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    try:
        return int(args.run(args) or 0)
    except DofviewError as e:
        print(f"dofview: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("dofview: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
