"""Make a training dataset from any dofview scene, through dofview's own GL renderer.

Every training view gets a random focus distance (uniform in inverse depth between the 10th and
90th percentile of what the view sees), a random f-number from a list and a random exposure
(log-uniform around the view's mid-grey key), is rendered with depth of field, tonemapped by
Eq. 7 (clip, then gamma) and quantised to 8 bits: a PNG whose eXIf chunk holds the settings.
Held-out views are rendered all-in-focus and kept as linear HDR EXRs for evaluation.

Nothing depends on the scene's units: the near plane is a fraction of the camera's distance to its
target, and the physical lens reads the scene at a size (``units_per_metre``) chosen so that the
widest aperture blurs the base view's depth range by a set fraction of the image width
(:func:`auto_units_per_metre`), unless the caller gives the size. Each photo's largest blur (CoC
radius in pixels over what it sees) is written beside its settings (``max_coc_px``). No depth
range is written: the trainer must find the geometry itself, from the photos alone or, with
``points``, from SfM-like points (:func:`sfm_points`) as a real capture's COLMAP run would give.
"""

from __future__ import annotations

import json
import math
import os
import shutil
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from dofview.camera import Camera, framing_camera, look_at
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.io.atomic import check_writable, make_folder
from dofview.io.exr import write_exr
from dofview.lens import Lens, PhysicalLens
from dofview.progress import Progress
from dofview.scene import GaussianScene
from dofview.tonemap import Tonemap, display, to_uint8
from dofview.train.exif import write_png_exif
from dofview.train.points import write_colmap_text

MID_GREY = 0.18
# What a camera sees: every Gaussian to its 3σ support, no τ cut (a cut darkens faint regions, which
# a camera would not), through the per-splat lens model (the one the trainer fits: photos made with
# another would ask for what it cannot draw); the photos, the held-out views, the trainer and the
# evaluation all use it.
PHOTO_RENDER = RenderSettings(tau=0.0, dof="splat")
NEAR_FRACTION = 1e-3  # the photos' near plane, as a fraction of the camera's distance to its target
# The auto lens: at the widest aperture, focused at the near end of the base view's depths (10th
# percentile), the far end (90th) is blurred by a CoC radius of this fraction of the image width.
BLUR_FRACTION = 0.02
MAX_MAGNIFICATION_DEPTH = 4.0  # the auto lens keeps the near depth ≥ this many focal lengths away


@dataclass(frozen=True)
class Capture:
    """How the virtual photographer shoots.

    Attributes:
        views, held_out: training photos and evaluation views.
        width, height: image size, pixels.
        focal_mm, sensor_mm: lens focal length and sensor width (fix the field of view).
        units_per_metre: scene units per metre (sets the aperture diameter f/N in scene units), or
            None: chosen from the scene by :func:`auto_units_per_metre`.
        ev_range: exposure offsets in stops from the view's key exposure, drawn uniformly.
        f_numbers: f-numbers drawn from.
        orbit_deg: cameras orbit the target by up to this yaw and half this pitch.
        gamma: γ of Eq. 7. seed: random seed.
        points: SfM-like points to write (COLMAP sparse/0/points3D.txt), 0 for none.
    """

    views: int = 30
    held_out: int = 8
    width: int = 64
    height: int = 48
    focal_mm: float = 50.0
    sensor_mm: float = 36.0
    units_per_metre: float | None = None
    ev_range: tuple[float, float] = (-10.0, 2.0)
    f_numbers: tuple[float, ...] = (1.4, 2.0, 2.8, 4.0, 5.6, 8.0)
    orbit_deg: float = 15.0
    gamma: float = 2.2
    seed: int = 0
    points: int = 0

    def __post_init__(self) -> None:
        if self.views < 1 or self.held_out < 0 or self.width < 8 or self.height < 8 or self.points < 0:
            raise DofviewError("need ≥ 1 view, ≥ 0 held-out views, ≥ 0 points and images of at least 8×8 pixels")
        if not (self.ev_range[0] <= self.ev_range[1]) or not self.f_numbers or min(self.f_numbers) <= 0:
            raise DofviewError("exposure range must be low ≤ high and f-numbers > 0")
        if self.units_per_metre is not None and not (math.isfinite(self.units_per_metre) and self.units_per_metre > 0):
            raise DofviewError(f"units per metre must be a finite value > 0, got {self.units_per_metre}")

    @property
    def fov_deg(self) -> float:
        return math.degrees(2 * math.atan(self.sensor_mm / (2 * self.focal_mm)))


def orbit(eye: np.ndarray, target: np.ndarray, yaw_deg: float, pitch_deg: float, capture: Capture) -> Camera:
    """The camera at ``eye`` swung about ``target`` by yaw (around world y) and pitch, looking at it."""
    off = np.asarray(eye, np.float64) - target
    y, p = math.radians(yaw_deg), math.radians(pitch_deg)
    off = np.array([math.cos(y) * off[0] + math.sin(y) * off[2], off[1], -math.sin(y) * off[0] + math.cos(y) * off[2]])
    horiz = math.hypot(off[0], off[2])
    elev = math.atan2(-off[1], horiz) + p  # world y points down: raising the eye is −y
    r = float(np.linalg.norm(off))
    scale = r * math.cos(elev) / max(horiz, 1e-12)
    new = np.array([off[0] * scale, -r * math.sin(elev), off[2] * scale])
    return look_at(target + new, target, capture.width, capture.height, capture.fov_deg)


def generate(scene: GaussianScene, out_dir: str | Path, capture: Capture = Capture(),
             eye=None, target=None, render: RenderSettings = PHOTO_RENDER, progress: bool = True,
             raster: str = "quad") -> Path:
    """Render a dataset of ``scene`` into the new folder ``out_dir`` with backend ``raster``
    (:func:`dofview.rendering.get_backend`); returns its transforms.json.

    The folder is built beside the target and renamed into place at the end, so a failure leaves
    nothing behind.
    """
    from dofview.rendering import get_backend

    out = Path(out_dir)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise DofviewError(f"{out}: already exists and is not an empty folder")
    check_writable(out)  # its folder: not under a file, one this process can write in
    if (eye is None) != (target is None):
        raise DofviewError("--eye and --target go together")
    if eye is None:
        base = framing_camera(scene, capture.width, capture.height, capture.fov_deg)
        eye = base.centre
        lo, hi = scene.robust_bounds()
        target = (lo + hi) / 2
    eye, target = np.asarray(eye, np.float64), np.asarray(target, np.float64)
    distance = float(np.linalg.norm(target - eye))
    if not distance > 0:
        raise DofviewError("--eye and --target must be different points")
    render = replace(render, near=NEAR_FRACTION * distance)
    rng = np.random.default_rng(capture.seed)
    angles = rng.uniform(-1, 1, (capture.views + capture.held_out, 2)) * [capture.orbit_deg, capture.orbit_deg / 2]
    renderer = get_backend(raster, scene)
    make_folder(out)  # as dofview render makes an output's folder
    tmp = out.parent / f".{out.name}.partial"
    shutil.rmtree(tmp, ignore_errors=True)
    (tmp / "images").mkdir(parents=True)
    (tmp / "hdr").mkdir()
    frames = []
    auto_units = capture.units_per_metre is None
    try:
        if auto_units:
            base = orbit(eye, target, 0.0, 0.0, capture)
            seen = renderer.render(base, Lens(1.0, 0.0), render)
            depths = seen.depth[_covered(seen, "the base view")]
            capture = replace(capture, units_per_metre=auto_units_per_metre(depths, base.fx, capture))
        with Progress(f"rendering dataset {out.name}", len(angles), delay=0.0 if progress else 1e9) as bar:
            for i, (yaw, pitch) in enumerate(angles):
                cam = orbit(eye, target, yaw, pitch, capture)
                pinhole = renderer.render(cam, Lens(1.0, 0.0), render)
                c2w = np.eye(4)
                c2w[:3, :3], c2w[:3, 3] = cam.R.T, cam.centre
                frame = {"transform_matrix": c2w.tolist()}
                if i >= capture.views:
                    name = f"hdr/view_{i - capture.views:03d}.exr"
                    write_exr(tmp / name, pinhole.rgba, pinhole.depth)
                    frames.append({**frame, "split": "test", "hdr_path": name})
                else:
                    frames.append({**frame, **_shoot(renderer, cam, pinhole, capture, render, rng, tmp, i)})
                bar.update(i + 1)
        if capture.points:
            shots = [f for f in frames if "exposure_time" in f]
            key = math.exp(np.mean([math.log(f["exposure_time"] / f["f_number"] ** 2) for f in shots]))
            (tmp / "sparse" / "0").mkdir(parents=True)
            write_colmap_text(tmp / "sparse" / "0" / "points3D.txt",
                              *sfm_points(scene, capture.points, eye, cam.fx, key, capture.gamma, rng))
        doc = {
            "camera_convention": "opencv", "w": capture.width, "h": capture.height,
            "fl_x": cam.fx, "fl_y": cam.fy, "cx": cam.cx, "cy": cam.cy,
            "sensor_mm": capture.sensor_mm, "units_per_metre": capture.units_per_metre, "gamma": capture.gamma,
            "generator": {"scene": scene.name, "colour_space": scene.colour_space, "gaussians": scene.count,
                          "eye": eye.tolist(), "target": target.tolist(), "seed": capture.seed,
                          "ev_range": list(capture.ev_range), "f_numbers": list(capture.f_numbers),
                          "orbit_deg": capture.orbit_deg, "points": capture.points,
                          "units_per_metre": "auto" if auto_units else capture.units_per_metre,
                          "blur_fraction": BLUR_FRACTION if auto_units else None, "near": render.near},
            "frames": frames,
        }
        (tmp / "transforms.json").write_text(json.dumps(doc, indent=1))
        if out.exists():
            out.rmdir()
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    finally:
        renderer.release()
    return out / "transforms.json"


def sfm_points(scene: GaussianScene, count: int, eye: np.ndarray, fx: float, key: float, gamma: float,
               rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """SfM-like points of ``scene``: (positions (count, 3) scene units, colours (count, 3) uint8).

    The means of ``count`` random Gaussians that are fairly opaque (opacity ≥ 0.5, where a
    reconstruction finds surfaces) and inside the scene's robust box (no floaters), each moved by
    Gaussian noise of one pixel's footprint (``fx`` pixels of focal length) at its distance from
    ``eye`` (a reprojection error of about a pixel); coloured as a photo at exposure ``key`` (t/N²)
    and gamma ``gamma`` shows the Gaussian's base colour. Fewer when the scene has fewer such
    Gaussians.
    """
    lo, hi = scene.robust_bounds()
    solid = np.nonzero((scene.opacities >= 0.5) & np.all((scene.means >= lo) & (scene.means <= hi), axis=1))[0]
    pick = rng.choice(solid, min(count, len(solid)), replace=False)
    means = scene.means[pick].astype(np.float64)
    sigma = np.linalg.norm(means - eye, axis=1) / fx
    positions = means + rng.normal(size=means.shape) * sigma[:, None]
    colour = scene.base_colour()[pick].astype(np.float64)
    radiance = colour if scene.colour_space == "linear" else colour ** gamma
    return positions, to_uint8(np.minimum(radiance * key, 1.0) ** (1.0 / gamma))


def _covered(pinhole, view: str) -> np.ndarray:
    """(H, W) bool: the pixels a pinhole render covers (α > ½); an error naming ``view`` when none."""
    covered = pinhole.alpha > 0.5
    if not covered.any():
        raise DofviewError(f"{view} sees nothing of the scene: give --eye/--target that look at it")
    return covered


def auto_units_per_metre(depths: np.ndarray, fx: float, capture: Capture) -> float:
    """Scene units per metre at which the widest aperture (min f-number), focused at the near end
    of ``depths`` (their 10th percentile, scene units), blurs the far end (90th) by a CoC radius of
    :data:`BLUR_FRACTION` of the image width; ``fx`` pixels of focal length.

    Eq. 3 with focus z_n: R = ½·f_x·(f/N)·z_n/(z_n − f)·(1/z_n − 1/z_f), solved for the focal
    length in scene units f = R·z_n/(c + R), c = ½·f_x·(1 − z_n/z_f)/N, and kept ≤ z_n /
    :data:`MAX_MAGNIFICATION_DEPTH` (a shallow scene would otherwise be shot at macro distance).
    Every depth scales with the scene, so the blur in pixels does not depend on its units.
    """
    near, far = (float(v) for v in np.percentile(depths, [10, 90]))
    c = 0.5 * fx * (1.0 - near / far) / min(capture.f_numbers)
    radius = BLUR_FRACTION * capture.width
    focal_units = min(radius * near / (c + radius), near / MAX_MAGNIFICATION_DEPTH)
    return focal_units / (capture.focal_mm * 1e-3)


def _shoot(renderer, cam: Camera, pinhole, capture: Capture, render: RenderSettings,
           rng: np.random.Generator, folder: Path, i: int) -> dict:
    """Take training photo ``i``: draw its settings, render with depth of field, write the PNG.
    ``capture.units_per_metre`` is set. The frame's ``max_coc_px`` is the photo's largest CoC
    radius (px) over the pixels the scene covers."""
    covered = _covered(pinhole, f"view {i}")
    depths = pinhole.depth[covered]
    near, far = np.percentile(depths, [10, 90])
    focus = 1.0 / rng.uniform(1.0 / far, 1.0 / near)
    luminance = pinhole.rgba[..., :3].mean(-1)[covered]
    key = MID_GREY / max(float(np.median(luminance)), 1e-6)
    exposure = key * 2.0 ** rng.uniform(*capture.ev_range)
    fnumber = float(rng.choice(capture.f_numbers))
    settings = {
        "exposure_time": exposure * fnumber ** 2, "f_number": fnumber,
        "focus_distance": float(focus), "focal_length_mm": capture.focal_mm,
    }
    lens = PhysicalLens(capture.focal_mm, fnumber, capture.sensor_mm, capture.units_per_metre).lens(cam.fx, focus)
    settings["max_coc_px"] = float(lens.coc_radius(depths).max())
    frame = renderer.render(cam, lens, render)
    photo = to_uint8(display(frame.rgba, frame.encoded, Tonemap(exposure=math.log2(exposure), gamma=capture.gamma)))
    name = f"images/view_{i:03d}.png"
    exif = {"exposure_time": settings["exposure_time"], "f_number": fnumber, "focal_length_mm": capture.focal_mm,
            "subject_distance_m": focus / capture.units_per_metre}
    write_png_exif(folder / name, photo, exif)
    return {"file_path": name, **settings}

