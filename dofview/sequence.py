"""Sequences: a focus pull and/or a camera path through training views, rendered frame by frame.

A shot is a list of :class:`Shot` entries (one camera and one focus per frame). Frames are written
to numbered files (``out/pull_%04d.exr``), each whole or not at all, so a shot can be cut into
frame ranges rendered on different machines and resumed after an interruption; a video is put
together from the finished frames.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np

from dofview.api import exr_header, read_header, save_render
from dofview.camera import Camera
from dofview.deep import DeepSettings
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.io.atomic import atomic_output
from dofview.lens import Lens
from dofview.progress import Progress
from dofview.rendering import Renderer
from dofview.scene import matrices_from_quats, quat_from_matrix
from dofview.tonemap import Tonemap, display, to_uint8
from dofview.tonemap.stats import Stats, StatsSmoother

_FRAME_NUMBER = re.compile(r"%0?\d*d")
# what a finished frame's header must agree on with the command for --resume to keep it
RECORDED = ("camera", "lens", "render", "exposure", "gamma", "tonemap", "frames")
VIDEO_FORMATS = {".mp4": "mp4", ".mov": "mov", ".mkv": "matroska"}


# ---- the shot ------------------------------------------------------------------------------------
def focus_pull(near: float, far: float, frames: int) -> list[float]:
    """``frames`` focus distances from ``near`` to ``far`` (either may be inf), evenly spaced in 1/z:
    the blur radius R = A/2·|1/z − 1/focus| is linear in 1/focus, so the pull looks even."""
    a, b = 1.0 / near, 1.0 / far
    ts = np.linspace(0.0, 1.0, frames) if frames > 1 else np.zeros(1)
    return [1.0 / v if v > 0 else math.inf for v in (a + (b - a) * ts)]


def slerp(R0: np.ndarray, R1: np.ndarray, t: float) -> np.ndarray:
    """(3, 3) rotation a fraction ``t`` of the shortest way from ``R0`` to ``R1`` (constant speed)."""
    q0, q1 = quat_from_matrix(R0), quat_from_matrix(R1)
    dot = float(q0 @ q1)
    if dot < 0:  # q and −q are the same rotation: take the short way round
        q1, dot = -q1, -dot
    theta = math.acos(min(dot, 1.0))
    if theta < 1e-9:
        return R0.copy()
    q = (math.sin((1 - t) * theta) * q0 + math.sin(t * theta) * q1) / math.sin(theta)
    return matrices_from_quats(q / np.linalg.norm(q))[0]


def between(a: Camera, b: Camera, t: float) -> Camera:
    """The camera a fraction ``t`` from ``a`` to ``b``: rotation slerped, centre and intrinsics
    (fx, fy, cx, cy, for ``a``'s image size: ``b`` is resized to it first) interpolated linearly."""
    b = b.resized(a.width, a.height)
    R = slerp(a.R, b.R, t)
    centre = (1 - t) * a.centre + t * b.centre

    def mix(u: float, v: float) -> float:
        return (1 - t) * u + t * v

    return replace(a, fx=mix(a.fx, b.fx), fy=mix(a.fy, b.fy), cx=mix(a.cx, b.cx), cy=mix(a.cy, b.cy),
                   R=R, T=-R @ centre, name=a.name if t < 0.5 else b.name)


def camera_path(cameras: list[Camera], first: int, last: int, frames: int, size: tuple[int, int]) -> list[Camera]:
    """``frames`` cameras along the training views ``first`` … ``last`` (either direction), evenly
    spaced in view index, each at image ``size`` (width, height)."""
    out = []
    for s in np.linspace(first, last, frames) if frames > 1 else [float(first)]:
        i = min(math.floor(s), len(cameras) - 1)
        t = s - i
        a = cameras[i].resized(*size)
        out.append(between(a, cameras[i + 1], t) if t > 1e-12 else a)
    return out


@dataclass(frozen=True)
class Shot:
    """One frame of a sequence: its number, camera and focus (scene units, inf allowed)."""

    index: int
    camera: Camera
    focus: float


# ---- output names --------------------------------------------------------------------------------
def frame_name(pattern: Path, index: int) -> Path:
    """The file of frame ``index``: ``pattern`` with its ``%04d`` (printf style) filled in; a name
    without a frame number (a one-frame shot) is that file."""
    text = str(pattern)
    return Path(text % index) if _FRAME_NUMBER.search(text) else Path(pattern)


def check_pattern(pattern: Path, what: str) -> None:
    """A sequence's output name must number its frames: exactly one ``%d``/``%04d`` and no other ``%``."""
    text = str(pattern)
    if len(_FRAME_NUMBER.findall(text)) != 1 or "%" in _FRAME_NUMBER.sub("", text).replace("%%", ""):
        raise DofviewError(f"{pattern}: {what} of a sequence needs one frame number such as %04d in its name "
                           f"(e.g. out/frame_%04d{pattern.suffix})")


# ---- rendering -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Outputs:
    """Where frames go: EXR and optional PNG and deep EXR name patterns, optional video and its frame rate."""

    exr: Path
    png: Path | None = None
    video: Path | None = None
    fps: float = 24.0
    half: bool = False
    deep: Path | None = None


def render_sequence(renderer: Renderer, shots: list[Shot], lens_for: Callable[[Camera, float], Lens],
                    tm: Tonemap, settings: RenderSettings, scene_path: str, out: Outputs,
                    frames: range, resume: bool = False, lens_info: dict[str, object] | None = None, log=print,
                    stats: Stats | None = None, lens_samples: int = 0, deep: DeepSettings = DeepSettings()) -> int:
    """Render the shots whose index is in ``frames`` to ``out``; returns how many were rendered.

    An adaptive tone-mapping operator gets ``stats`` (``--stats joint``: fixed for the shot) or else
    each frame's statistics smoothed in time as the viewer smooths them, with the frame interval
    1/fps as Δt (a skipped or resumed frame does not advance the smoothing). ``lens_samples`` > 0
    renders each frame as the physical thin lens from that many pinhole passes. With ``out.deep``
    each frame's deep image is written too (made with ``deep``; its header as the EXR's, plus
    ``dofview:deep``).

    Each EXR carries its frame's camera, focus and aperture (api.exr_header) and
    ``dofview:frame``/``dofview:frames``. With ``resume``, frames whose files all exist are skipped
    (files are written whole or not at all, so an existing one is complete) when their header (and
    the deep image's) records the camera, lens and settings this command gives them (:func:`stale_setting`); the
    others are rendered again, and the summary line says how many. The video, when asked for, is
    made from every frame of the shot, rendered now or found on disk.
    """
    total = len(shots)
    todo = [s for s in shots if s.index in frames]
    rendered, stale = 0, {}
    smoother = StatsSmoother() if stats is None and tm.operator.adaptive else None
    with Progress(f"rendering {len(todo)} frames", len(todo), unit=" frames") as bar:
        for n, shot in enumerate(todo):
            exr, png = frame_name(out.exr, shot.index), out.png and frame_name(out.png, shot.index)
            deep_exr = out.deep and frame_name(out.deep, shot.index)
            lens = lens_for(shot.camera, shot.focus)
            frame_keys = {"dofview:frame": shot.index, "dofview:frames": total}
            there = resume and all(p is None or p.is_file() for p in (exr, png, deep_exr))
            changed = None
            if there:
                expected = {**exr_header(shot.camera, lens, tm, settings, renderer.scene.colour_space, scene_path,
                                         lens_info), **frame_keys}
                changed = stale_setting(exr, expected, lens_samples)
                if changed is None and deep_exr is not None:
                    changed = stale_setting(deep_exr, {**expected, "dofview:deep": json.dumps(deep.to_dict())},
                                            lens_samples)
                if changed is not None:
                    stale[changed] = stale.get(changed, 0) + 1
            if not there or changed is not None:
                save_render(renderer, shot.camera, lens, tm, settings, scene_path, exr, png, half=out.half,
                            lens_info=lens_info, header=frame_keys,
                            stats=stats, smoother=smoother, dt=1.0 / out.fps, lens_samples=lens_samples,
                            deep=deep_exr, deep_settings=deep)
                rendered += 1
            bar.update(n + 1, info=exr.name)
    if out.video is not None:
        write_video(out, [s.index for s in shots], renderer.scene.colour_space == "srgb", tm)
    redone = (f" ({sum(stale.values())} of them again: their recorded "
              + ", ".join(f"{key} ({count})" for key, count in stale.items()) + " differed from this command)"
              if stale else "")
    log(f"{out.exr}: frames {frames.start}–{frames.stop - 1} of {total}: {rendered} rendered{redone}, "
        f"{len(todo) - rendered} already there" + (f"; {out.video}" if out.video else ""))
    return rendered


def stale_setting(exr: Path, expected: dict[str, object], lens_samples: int) -> str | None:
    """What a finished frame's EXR header (flat or deep) records differently from ``expected``
    (api.exr_header of the frame this command would render): the first differing name of
    :data:`RECORDED`, "lens_samples", "scene" or (where ``expected`` has ``dofview:deep``) "deep";
    "header" when the file cannot be read; None when it agrees.

    Both sides are read back through api.read_header and written out again by each type's
    ``to_dict`` (:func:`_recorded`), so they compare in one form, and a header written before an
    entry was recorded (``near``) holds that entry's default. Numbers agree to a relative 1e-5
    (EXR stores float attributes in single precision, and an auto focus may differ in its last
    digits on another machine of a farm)."""
    from dofview.io.exr import read_exr_header

    try:
        header = read_exr_header(exr)
        recorded = _recorded(header)
        deep = DeepSettings.from_dict(json.loads(header["dofview:deep"])) if "dofview:deep" in header else None
    except (DofviewError, ValueError, TypeError, AttributeError):
        return "header"
    wanted = _recorded(expected)
    for name in RECORDED:
        if not _same(recorded.get(name), wanted.get(name)):
            return name
    if int(header.get("dofview:lens_samples", 0)) != lens_samples:
        return "lens_samples"
    recorded_scene = header.get("dofview:scene")
    if recorded_scene is None or Path(str(recorded_scene)).resolve() != Path(str(expected["dofview:scene"])).resolve():
        return "scene"
    if "dofview:deep" in expected and (deep is None or deep.to_dict() != json.loads(str(expected["dofview:deep"]))):
        return "deep"
    return None


def _recorded(header: dict[str, object]) -> dict[str, object]:
    """The :data:`RECORDED` entries of an EXR header as plain data: each object read back
    (api.read_header) and written out by its own ``to_dict``; absent entries are missing."""
    r = read_header(header)
    out = {name: r[name] for name in ("exposure", "gamma", "frames") if name in r}
    if "camera" in r:
        out["camera"] = r["camera"].to_dict()
    if "lens" in r:
        out["lens"] = {**r["lens"].to_dict(), **r["lens_request"].to_dict()}
    if "settings" in r:
        out["render"] = {**r["settings"].to_dict(), "colour_space": r["colour_space"]}
    if "tonemap" in r:
        out["tonemap"] = r["tonemap"].to_dict()["tonemap"]
    return out


def _same(a: object, b: object) -> bool:
    """Equal, numbers to a relative 1e-5, through dicts and lists."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool) and not isinstance(b, bool):
        return math.isclose(a, b, rel_tol=1e-5, abs_tol=1e-9)
    return a == b


def _finished_image(out: Outputs, index: int, encoded: bool, tm: Tonemap) -> np.ndarray:
    """(H, W, 3) uint8 display image of a finished frame: its PNG, or its EXR tone mapped again."""
    png = out.png and frame_name(out.png, index)
    if png is not None and png.is_file():
        from dofview.io.png import read_png

        return read_png(png)[..., :3]
    from dofview.io.exr import read_exr

    exr = frame_name(out.exr, index)
    if not exr.is_file():
        raise DofviewError(f"{exr}: frame {index} is missing; render every frame (or --resume) before --video")
    channels, _ = read_exr(exr)
    rgba = np.stack([channels[c] for c in "RGBA"], -1).astype(np.float32)
    return to_uint8(display(rgba, encoded, replace(tm, exposure=0.0)))  # the EXR is already exposed


def check_video(path: Path) -> str:
    """The ffmpeg format name for a video file name; refuses other endings, or a missing imageio-ffmpeg."""
    fmt = VIDEO_FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise DofviewError(f"{path}: a video must end in one of {', '.join(VIDEO_FORMATS)}")
    try:
        import imageio_ffmpeg  # noqa: F401
    except ImportError:
        raise DofviewError(f"{path}: writing video needs imageio-ffmpeg (pip install 'dofview[video]')") from None
    return fmt


def write_video(out: Outputs, indices: list[int], encoded: bool, tm: Tonemap) -> None:
    """H.264 video of the frames ``indices`` through imageio-ffmpeg (its own ffmpeg binary), written
    whole or not at all."""
    fmt = check_video(out.video)
    import imageio_ffmpeg

    first = _finished_image(out, indices[0], encoded, tm)
    h, w = first.shape[:2]
    with atomic_output(out.video) as tmp:
        # yuv420p needs even sizes: pad odd ones by a pixel rather than resample
        writer = imageio_ffmpeg.write_frames(str(tmp), (w, h), fps=out.fps, codec="libx264", quality=8,
                                             macro_block_size=1, ffmpeg_log_level="error",
                                             output_params=["-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-f", fmt])
        writer.send(None)
        try:
            for n, index in enumerate(indices):
                image = first if n == 0 else _finished_image(out, index, encoded, tm)
                if image.shape[:2] != (h, w):
                    raise DofviewError(f"{out.video}: frame {index} is {image.shape[1]}×{image.shape[0]}, "
                                       f"frame {indices[0]} {w}×{h}")
                writer.send(np.ascontiguousarray(image))
        finally:
            writer.close()
