"""Command-line options shared by ``render``, ``view``, ``bench`` and ``train``: the value parsers
(each rejects a bad value with a one-line argparse error), the option groups, and the one
``dofview render`` line that reproduces a view (:func:`render_command_line`). The objects the
options ask for are built by :mod:`dofview.request`.
"""

from __future__ import annotations

import argparse
import math
import shlex
from pathlib import Path
from typing import Callable

from dofview.camera import REFERENCE_WIDTH, Camera
from dofview.errors import DofviewError
from dofview.frame import BLADES_MAX, CUT_MODES, DOF_MODES, KERNELS, OPACITY_NORMS, RenderSettings
from dofview.framing import UP_AXES
from dofview.io.lod import DEFAULT_BUDGET as LOD_BUDGET
from dofview.io.spz import AXES as SPZ_AXES
from dofview.lens import BlurSpec, Lens
from dofview.rendering import AUTO_ORDER, BACKENDS
from dofview.scene import COLOUR_SPACES
from dofview.tonemap import Tonemap

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


def gaussian_count(text: str) -> int:
    """A number of Gaussians ≥ 1: a whole number, or one with a k (thousand) or M (million) suffix."""
    scale = {"k": 1_000, "m": 1_000_000}.get(text[-1:].lower(), 1)
    try:
        v = float(text[:-1] if scale > 1 else text) * scale
    except ValueError:
        raise argparse.ArgumentTypeError(f"--budget must be a number of Gaussians (e.g. 3M, 500k), got {text!r}") from None
    if not math.isfinite(v) or v < 1 or v != int(v):
        raise argparse.ArgumentTypeError(f"--budget must be a whole number of Gaussians ≥ 1, got {text!r}")
    return int(v)


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
    """An axis label such as -y (a bare y is +y), or a direction x,y,z (kept as text:
    :class:`UpGuess` reads it)."""
    if text in UP_AXES:
        return text
    if f"+{text}" in UP_AXES:
        return f"+{text}"
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
    try:
        return BlurSpec.parse(text)
    except DofviewError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


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
    g = p.add_argument_group("streamed LOD sets (lod-meta.json)")
    g.add_argument("--lod", type=number(0, None, integer=True, what="--lod"),
                   help="the level to draw, 0 the finest (default: the finest within --budget; the viewer "
                        "mixes levels, finer near the camera)")
    g.add_argument("--budget", type=gaussian_count, default=None,
                   help=f"most Gaussians drawn, e.g. 3M or 500k (default {LOD_BUDGET:,})")


def add_view_args(p: argparse.ArgumentParser, default_size: tuple[int, int] = (800, 600)) -> None:
    g = p.add_argument_group("camera")
    g.add_argument("--width", type=number(1, None, integer=True, what="width"), help=f"image width (default {default_size[0]}, or the camera's)")
    g.add_argument("--height", type=number(1, None, integer=True, what="height"), help=f"image height (default {default_size[1]}, or the camera's)")
    g.add_argument("--cameras", type=Path, help="Inria cameras.json")
    g.add_argument("--view", default="0", help="camera index or image name in --cameras (default 0)")
    g.add_argument("--eye", type=vec3, help="camera position x,y,z (scene units)")
    g.add_argument("--target", type=vec3, help="point looked at x,y,z (scene units)")
    g.add_argument("--fov", type=number(0, 180, lo_open=True, what="field of view"), help="horizontal field of view, degrees (default 50)")
    g.add_argument("--near", type=number(0, None, lo_open=True, what="near plane"), default=RenderSettings.near,
                   help=f"near plane, scene units (default {RenderSettings.near:g})")
    g.add_argument("--up", type=up_value, help=f"world up: {'|'.join(UP_AXES)} (y is +y) or a direction x,y,z "
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
                   help="depth of field by the blur it makes: the largest blur on what the picture shows (2nd–98th "
                        "percentile depths of the pixels of a pinhole pass with fine detail at one depth) has radius "
                        "R px at the reference width, or R%% of the image width; R ≤ 25%% of the width; R@DEPTH "
                        "gives that blur to camera depth DEPTH (e.g. 6@inf: the far background)")
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
    g.add_argument("--dof", choices=DOF_MODES, default=RenderSettings.dof, help="depth of field: blend depth slices as a pinhole and blur each slice with the aperture (rendering/sliced.py; the default), or blur each splat (the published single pass; --k, --opacity-norm, --cut and --kernel shape it)")
    g.add_argument("--blades", type=number(0, BLADES_MAX, hi_open=False, integer=True, what="blades"), default=0, help=f"aperture blades of --dof sliced: 0 = a round disk (default), 3…{BLADES_MAX} a regular polygon")
    g.add_argument("--blade-rotation", type=number(what="blade rotation"), default=0.0, metavar="DEG", help="rotation of the --blades polygon's first corner, degrees from image right (default 0)")


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


def render_command_line(scene_path: str, camera: Camera, lens: Lens, tm: Tonemap, settings: RenderSettings,
                        colour_space: str, out: str = "out.exr") -> str:
    """A ``dofview render`` line that reproduces a view (the viewer's "copy as command"), from the
    command-line form of each object: :meth:`Camera.to_args` (an --eye/--target camera whose
    target is the focus distance ahead), :meth:`Lens.to_args` (the strength at that camera's
    reference width, so the same line with another --width gives the same picture, scaled),
    :meth:`Tonemap.to_args` and :meth:`RenderSettings.to_args`."""
    parts = ["dofview", "render", scene_path, "-o", out,
             *camera.to_args(lens.focus if math.isfinite(lens.focus) else 1.0),
             *lens.to_args(camera.width, REFERENCE_WIDTH), *tm.to_args(colour_space), *settings.to_args(),
             "--colour-space", colour_space]
    return shlex.join(parts)
