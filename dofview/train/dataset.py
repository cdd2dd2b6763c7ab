"""Training datasets: a folder of 8-bit photos plus ``transforms.json`` (format in docs/TRAINING.md).

Each training frame needs a camera (intrinsics and a camera-to-world matrix) and its capture
settings: exposure time t (s), f-number N, focus distance d_f (scene units) and focal length
(mm). A setting missing from the frame is taken from the file's top level, then from the image's
EXIF (ExposureTime, FNumber, FocalLength, SubjectDistance in metres); an image whose settings stay
unknown is named in the error. Held-out frames (``"split": "test"``) carry an all-in-focus linear
HDR EXR (``hdr_path``) for evaluation instead of a photo. Structure-from-motion points, when the
dataset has them (:func:`find_points`), start the fit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.io.jsonfile import read_json
from dofview.lens import Lens, PhysicalLens, exposure_from_shutter
from dofview.train.exif import read_exif
from dofview.train.points import PointCloud, read_points

SETTINGS = ("exposure_time", "f_number", "focus_distance", "focal_length_mm")
NEAR_FRACTION = 0.01  # the trainer's and the evaluation's near plane, as a fraction of the scene's near depth


@dataclass(frozen=True)
class Shot:
    """One training photo and how it was taken.

    Attributes:
        camera: pinhole camera (OpenCV convention) of the photo.
        path: the 8-bit image file.
        exposure_time: t in seconds. f_number: N. focus: d_f, camera z-depth in scene units.
        focal_mm: focal length in mm.
    """

    camera: Camera
    path: Path
    exposure_time: float
    f_number: float
    focus: float
    focal_mm: float

    @property
    def exposure(self) -> float:
        """Linear exposure multiplier t/N² (Eq. 7)."""
        return exposure_from_shutter(self.exposure_time, self.f_number)

    def lens(self, sensor_mm: float, units_per_metre: float) -> Lens:
        """The thin lens of this photo (Eq. 3) with the camera's own f_x."""
        return PhysicalLens(self.focal_mm, self.f_number, sensor_mm, units_per_metre).lens(self.camera.fx, self.focus)


@dataclass(frozen=True)
class HeldOut:
    """A held-out view: camera and its all-in-focus linear HDR render (EXR with R, G, B, A)."""

    camera: Camera
    hdr_path: Path


@dataclass(frozen=True)
class Dataset:
    """A loaded ``transforms.json``.

    Attributes:
        root: the dataset folder. shots: training photos. held_out: evaluation views.
        sensor_mm: sensor width in mm. units_per_metre: scene units per metre.
        gamma: the photos' transfer gamma γ of Eq. 7.
        depth_range: (near, far) camera depths in scene units where the scene lies, or None.
        points: structure-from-motion points in the world frame of the cameras, or None.
    """

    root: Path
    shots: tuple[Shot, ...]
    held_out: tuple[HeldOut, ...]
    sensor_mm: float
    units_per_metre: float
    gamma: float
    depth_range: tuple[float, float] | None
    points: PointCloud | None = None

    def lenses(self) -> list[Lens]:
        return [s.lens(self.sensor_mm, self.units_per_metre) for s in self.shots]

    def key_exposure(self) -> float:
        """Geometric mean of the training exposures t/N²."""
        return float(np.exp(np.mean([math.log(s.exposure) for s in self.shots])))

    def scene_depths(self) -> tuple[float, float]:
        """(near, far) scene depths (scene units): ``depth_range``, else ½× the nearest and 2× the
        farthest finite focus, else the 2nd–98th percentile of the SfM points' depths in the
        cameras, widened the same way. Every length the trainer uses is relative to these, so
        its behaviour does not depend on the scene's units."""
        if self.depth_range is not None:
            return self.depth_range
        focus = [s.focus for s in self.shots if math.isfinite(s.focus)]
        if not focus and self.points is not None:
            z = np.concatenate([s.camera.world_to_camera(self.points.positions)[:, 2] for s in self.shots])
            focus = list(np.percentile(z[z > 0], [2, 98])) if (z > 0).any() else []
        if not focus:
            raise DofviewError(f"{self.root}: cannot tell where the scene lies (every photo is focused at infinity "
                               "and there are no SfM points in front of the cameras): give depth_range")
        return 0.5 * min(focus), 2.0 * max(focus)

    def subject_distance(self) -> float:
        """Where the photographer focused: the median finite focus distance (scene units), else the
        geometric mean of :meth:`scene_depths`. The trainer's position learning rate is relative to it."""
        focus = [s.focus for s in self.shots if math.isfinite(s.focus)]
        return float(np.median(focus)) if focus else math.sqrt(math.prod(self.scene_depths()))

    def near_plane(self) -> float:
        """The near plane (camera z, scene units) of the trainer's and the evaluation's renders:
        :data:`NEAR_FRACTION` of the near scene depth."""
        return NEAR_FRACTION * self.scene_depths()[0]


def _camera(path: Path, where: str, top: dict, frame: dict) -> Camera:
    get = lambda k: frame.get(k, top.get(k))  # noqa: E731 - per-frame value, else the file's default
    try:
        w, h = int(get("w")), int(get("h"))
        fx = float(get("fl_x"))
        fy = float(get("fl_y") if get("fl_y") is not None else fx)
        cx = float(get("cx") if get("cx") is not None else w / 2)
        cy = float(get("cy") if get("cy") is not None else h / 2)
        c2w = np.asarray(frame["transform_matrix"], dtype=np.float64)
    except (KeyError, TypeError, ValueError) as e:
        raise DofviewError(f"{path}: {where}: missing or malformed camera field ({e!r})") from None
    if c2w.shape not in ((4, 4), (3, 4)) or not np.all(np.isfinite(c2w)) or not (w > 0 and h > 0 and fx > 0 and fy > 0):
        raise DofviewError(f"{path}: {where}: camera must have w, h, fl_x > 0 and a finite 4×4 transform_matrix")
    rot, centre = c2w[:3, :3].copy(), c2w[:3, 3]
    if top.get("camera_convention", "opencv") == "opengl":  # y up, z backward → OpenCV y down, z forward
        rot[:, 1:3] *= -1
    R = rot.T
    return Camera(w, h, fx, fy, cx, cy, R, -R @ centre, name=str(frame.get("file_path", frame.get("hdr_path", where))))


def load_dataset(path: str | Path) -> Dataset:
    """Read a dataset folder (or its transforms.json) and every training photo's settings."""
    path = Path(path)
    file = path / "transforms.json" if path.is_dir() else path
    top = read_json(file, "dataset")
    if not isinstance(top, dict) or not isinstance(top.get("frames"), list):
        raise DofviewError(f"{file}: expected an object with a 'frames' list")
    root = file.parent
    try:
        sensor = float(top.get("sensor_mm", 36.0))
        upm = float(top.get("units_per_metre", 1.0))
        gamma = float(top.get("gamma", 2.2))
        depth_range = tuple(float(v) for v in top["depth_range"]) if "depth_range" in top else None
    except (TypeError, ValueError) as e:
        raise DofviewError(f"{file}: malformed sensor_mm/units_per_metre/gamma/depth_range ({e})") from None
    if not all(math.isfinite(v) and v > 0 for v in (sensor, upm, gamma)):
        raise DofviewError(f"{file}: sensor_mm, units_per_metre and gamma must be finite and > 0")
    shots, held, unknown = [], [], []
    for i, frame in enumerate(top["frames"]):
        if not isinstance(frame, dict):
            raise DofviewError(f"{file}: frame {i} is not an object")
        where = f"frame {i}"
        camera = _camera(file, where, top, frame)
        if frame.get("split", "train") == "test":
            if "hdr_path" not in frame:
                raise DofviewError(f"{file}: held-out {where} has no hdr_path")
            held.append(HeldOut(camera, root / frame["hdr_path"]))
            continue
        if "file_path" not in frame:
            raise DofviewError(f"{file}: {where} has no file_path")
        image = root / frame["file_path"]
        if not image.is_file():
            raise DofviewError(f"{file}: {where}: image {image} does not exist")
        values = {k: frame.get(k, top.get(k)) for k in SETTINGS}
        if any(v is None for v in values.values()):
            exif = read_exif(image)
            if "subject_distance_m" in exif:
                exif["focus_distance"] = exif["subject_distance_m"] * upm
            values = {k: exif.get(k) if v is None else v for k, v in values.items()}
        missing = [k for k, v in values.items() if v is None]
        if missing:
            unknown.append(f"{frame['file_path']} ({', '.join(missing)})")
            continue
        try:
            t, n, d, f = (float(values[k]) for k in SETTINGS)
        except (TypeError, ValueError):
            raise DofviewError(f"{file}: {image}: capture settings must be numbers, got {values}") from None
        if not (t > 0 and n > 0 and d > 0 and f > 0) or not all(map(math.isfinite, (t, n, f))):
            raise DofviewError(f"{file}: {image}: exposure time, f-number, focus and focal length must be > 0")
        shots.append(Shot(camera, image, t, n, d, f))
    if unknown:
        raise DofviewError(f"{file}: capture settings unknown (neither in transforms.json nor in EXIF) for: "
                           + "; ".join(unknown))
    if not shots:
        raise DofviewError(f"{file}: no training frames")
    return Dataset(root, tuple(shots), tuple(held), sensor, upm, gamma, depth_range,  # type: ignore[arg-type]
                   find_points(file, top))


POINTS_KEYS = ("points3D", "ply_file_path")  # ours, and nerfstudio's name for its sparse_pc.ply
COLMAP_FOLDERS = ("sparse/0", "colmap/sparse/0")  # beside the images: COLMAP's, and ns-process-data's layout


def find_points(file: Path, top: dict) -> PointCloud | None:
    """The dataset's SfM points: the file named by ``points3D`` or ``ply_file_path`` in
    transforms.json (relative to its folder, in the cameras' frame), else COLMAP's
    ``points3D.bin``/``.txt`` in ``sparse/0`` or ``colmap/sparse/0`` beside it, moved into the
    cameras' frame by the file's ``applied_transform`` (3×4 or 4×4) when it has one, as
    nerfstudio writes; None when there are none."""
    root = file.parent
    for key in POINTS_KEYS:
        if key in top:
            if not isinstance(top[key], str):
                raise DofviewError(f"{file}: {key} must name a points file, got {top[key]!r}")
            return read_points(root / top[key])
    found = [root / d / n for d in COLMAP_FOLDERS for n in ("points3D.bin", "points3D.txt")]
    path = next((p for p in found if p.is_file()), None)
    if path is None:
        return None
    cloud = read_points(path)
    if "applied_transform" not in top:
        return cloud
    try:
        m = np.asarray(top["applied_transform"], dtype=np.float64)
        if m.shape not in ((3, 4), (4, 4)) or not np.all(np.isfinite(m)):
            raise ValueError(f"shape {m.shape}")
    except (TypeError, ValueError) as e:
        raise DofviewError(f"{file}: applied_transform must be a finite 3×4 or 4×4 matrix ({e})") from None
    return PointCloud(cloud.positions @ m[:3, :3].T + m[:3, 3], cloud.colours, cloud.path)


def load_photo(shot: Shot) -> np.ndarray:
    """(H, W, 3) float32 pixel values in [0, 1] of an 8-bit PNG photo, checked against its camera."""
    from dofview.io.png import read_png

    try:
        img = read_png(shot.path)
    except DofviewError:  # a camera's JPEG or a filtered PNG: needs Pillow (comes with matplotlib)
        try:
            from PIL import Image
        except ImportError:
            raise DofviewError(f"{shot.path}: only dofview's own PNGs are read without Pillow "
                               "(pip install pillow)") from None
        try:
            img = np.asarray(Image.open(shot.path).convert("RGB"))
        except OSError as e:
            raise DofviewError(f"{shot.path}: cannot read image ({e})") from None
    if img.shape[:2] != (shot.camera.height, shot.camera.width):
        raise DofviewError(f"{shot.path}: image is {img.shape[1]}×{img.shape[0]}, the camera says "
                           f"{shot.camera.width}×{shot.camera.height}")
    return img[..., :3].astype(np.float32) / 255.0
