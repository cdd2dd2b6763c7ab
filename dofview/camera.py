"""Pinhole cameras in the OpenCV convention (x right, y down, z forward), world → camera.

Pixel coordinates are continuous with (0, 0) at the top-left corner of the image, so the centre
of pixel (i, j) is (i + 0.5, j + 0.5) and a point projects to (fx·x/z + cx, fy·y/z + cy).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from dofview.errors import DofviewError

# The image width at which an aperture strength A is meant for a camera without a size of its own
# (--eye/--target, the automatic framing): ``dofview render``'s default width.
REFERENCE_WIDTH = 800


@dataclass(frozen=True)
class Camera:
    """A pinhole camera.

    Attributes:
        width, height: image size in pixels.
        fx, fy: focal lengths in pixels.
        cx, cy: principal point in pixels (continuous coordinates, see module docstring).
        R: (3, 3) float64 world → camera rotation (rows are the camera axes in world space).
        T: (3,) float64 world → camera translation, scene units: x_cam = R x_world + T.
        name: an image name when the camera came from cameras.json.
        ref_width: the image width in pixels at which an aperture strength A holds as given
            (0 at construction: this camera's own width). :meth:`resized` keeps it, so
            :meth:`scaled_aperture` makes A follow f_x (A = f_x·D, D the lens diameter) and the
            same command at another size gives the same picture, scaled.
        guard: pixels by which this image extends beyond the frame on every side (the sliced
            mode's guard band, :meth:`guarded`): width, height, cx and cy are the extended image's,
            and the EWA frustum clamp (:meth:`frustum_limits`) keeps to the frame inside it.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    R: np.ndarray
    T: np.ndarray
    name: str = ""
    ref_width: int = 0
    guard: int = 0

    def __post_init__(self) -> None:
        if self.ref_width <= 0:
            object.__setattr__(self, "ref_width", int(self.width))
        object.__setattr__(self, "R", np.asarray(self.R, dtype=np.float64).reshape(3, 3))
        object.__setattr__(self, "T", np.asarray(self.T, dtype=np.float64).reshape(3))

    @property
    def centre(self) -> np.ndarray:
        """(3,) float64: the camera centre in world space, scene units."""
        return -self.R.T @ self.T

    @property
    def forward(self) -> np.ndarray:
        """(3,) float64: the viewing direction (camera +z) in world space."""
        return self.R[2].copy()

    def view_key(self) -> bytes:
        """Bytes that change exactly when the depth order of the scene can change."""
        return np.concatenate([self.R.ravel(), self.T]).tobytes()

    def world_to_camera(self, points: np.ndarray) -> np.ndarray:
        """(N, 3) world points → (N, 3) float64 camera-space points, scene units."""
        return np.asarray(points, dtype=np.float64) @ self.R.T + self.T

    def project(self, points: np.ndarray) -> np.ndarray:
        """(N, 3) world points → (N, 2) float64 pixel coordinates."""
        t = self.world_to_camera(points)
        return np.stack([self.fx * t[:, 0] / t[:, 2] + self.cx, self.fy * t[:, 1] / t[:, 2] + self.cy], axis=1)

    def scaled_aperture(self, aperture: float) -> float:
        """Aperture strength A (px·scene unit) at this image width for a strength given at
        :attr:`ref_width`: A·width/ref_width, and ``aperture`` itself, bit for bit, at that width."""
        return aperture if self.width == self.ref_width else aperture * self.width / self.ref_width

    def resized(self, width: int, height: int) -> "Camera":
        """The same view at another image size: fx, cx scale with width and fy, cy with height."""
        sx, sy = width / self.width, height / self.height
        return replace(self, width=int(width), height=int(height), fx=self.fx * sx, fy=self.fy * sy,
                       cx=self.cx * sx, cy=self.cy * sy)

    def guarded(self, pixels: int) -> "Camera":
        """This view's image extended by ``pixels`` on every side (a guard band): the frame's pixels
        keep their coordinates shifted by ``pixels``, and every Gaussian its footprint, since the
        frustum clamp stays the frame's (:meth:`frustum_limits`)."""
        return replace(self, width=self.width + 2 * pixels, height=self.height + 2 * pixels, cx=self.cx + pixels,
                       cy=self.cy + pixels, guard=self.guard + pixels)

    def frustum_limits(self) -> tuple[float, float, float, float]:
        """(lo_x, lo_y, hi_x, hi_y) the limits of x/z and y/z to which EWA splatting clamps a mean
        for its Jacobian (project.glsl): 15 % of the frame beyond its edges (the frame inside a
        guard band), so that Gaussians far off screen keep a bounded footprint."""
        g = self.guard
        w, h, cx, cy = self.width - 2 * g, self.height - 2 * g, self.cx - g, self.cy - g
        return ((-cx - 0.15 * w) / self.fx, (-cy - 0.15 * h) / self.fy,
                (w - cx + 0.15 * w) / self.fx, (h - cy + 0.15 * h) / self.fy)

    def lens_shifted(self, u: float, v: float, focus: float) -> "Camera":
        """The pinhole camera seen from lens point (u, v) (scene units, camera x/y) that keeps the
        plane z = focus fixed: centre moved by (u, v), principal point by (fx·u/focus, fy·v/focus).
        """
        return replace(self, T=self.T - np.array([u, v, 0.0]), cx=self.cx + self.fx * u / focus,
                       cy=self.cy + self.fy * v / focus)

    def pixel_ray(self, px: float, py: float) -> np.ndarray:
        """(3,) float64 world-space direction through pixel coordinates (px, py), with camera z = 1."""
        d = np.array([(px - self.cx) / self.fx, (py - self.cy) / self.fy, 1.0])
        return self.R.T @ d

    @property
    def fov_x_deg(self) -> float:
        return math.degrees(2 * math.atan(self.width / (2 * self.fx)))

    def to_dict(self) -> dict[str, object]:
        """The camera as plain data (the EXR header's ``dofview:camera``, the API): size, intrinsics
        (pixels), R and T as nested lists, ref_width. ``name`` is a label, not part of the view: it
        is left out, so a frame's header compares equal whichever file the view came from."""
        return {"width": self.width, "height": self.height, "fx": self.fx, "fy": self.fy, "cx": self.cx,
                "cy": self.cy, "R": self.R.tolist(), "T": self.T.tolist(), "ref_width": self.ref_width}

    @classmethod
    def from_dict(cls, d: dict[str, object]) -> "Camera":
        """The camera of :meth:`to_dict` (a header without ``ref_width``: the camera's own width).

        Raises:
            DofviewError: a missing or malformed entry, named.
        """
        try:
            return cls(int(d["width"]), int(d["height"]), float(d["fx"]), float(d["fy"]), float(d["cx"]),
                       float(d["cy"]), np.array(d["R"], dtype=np.float64), np.array(d["T"], dtype=np.float64),
                       ref_width=int(d.get("ref_width", 0)))
        except (KeyError, TypeError, ValueError) as e:
            raise DofviewError(f"camera record: missing or malformed entry ({e})") from None

    def to_args(self, target_distance: float = 1.0) -> list[str]:
        """``dofview render`` arguments for this view: --width/--height, --eye at the centre,
        --target ``target_distance`` scene units ahead, --up the image-up direction (keeps the
        roll) and --fov, all at full float precision. They give back this camera (to the last
        bits of the float64 rotation) for a centred principal point and square pixels, with the
        reference width of an --eye/--target camera (:data:`REFERENCE_WIDTH`)."""
        eye = self.centre
        target = eye + self.forward * target_distance

        def joined(v) -> str:
            return ",".join(repr(float(x)) for x in v)

        # "--eye=…" form: argparse would take a value like "-1.5,0,2" for an option
        return ["--width", str(self.width), "--height", str(self.height), f"--eye={joined(eye)}",
                f"--target={joined(target)}", f"--up={joined(-self.R[1])}", "--fov", repr(self.fov_x_deg)]


def look_at(eye, target, width: int, height: int, fov_deg: float = 50.0, up=(0.0, -1.0, 0.0)) -> Camera:
    """A camera at ``eye`` looking at ``target``; ``fov_deg`` is the horizontal field of view.

    ``up`` is the world direction that appears up in the image. The default (0, −1, 0) matches
    OpenCV/COLMAP scenes, where world y points down.
    """
    eye = np.asarray(eye, dtype=np.float64)
    fwd = np.asarray(target, dtype=np.float64) - eye
    if not np.all(np.isfinite(fwd)) or np.linalg.norm(fwd) == 0:
        raise DofviewError("camera eye and target must be distinct finite points")
    fwd /= np.linalg.norm(fwd)
    up = np.asarray(up, dtype=np.float64)
    right = np.cross(fwd, up)  # camera x = forward × up gives x right when up is image-up
    if np.linalg.norm(right) < 1e-9:  # looking straight along up: pick any perpendicular
        right = np.cross(fwd, np.array([1.0, 0, 0]) if abs(fwd[0]) < 0.9 else np.array([0, 0, 1.0]))
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    R = np.stack([right, down, fwd])
    if not 0.0 < fov_deg < 180.0:
        raise DofviewError(f"field of view must be between 0 and 180 degrees, got {fov_deg}")
    fx = width / (2 * math.tan(math.radians(fov_deg) / 2))
    return Camera(width, height, fx, fx, width / 2, height / 2, R, -R @ eye)


def framing_camera(scene, width: int, height: int, fov_deg: float = 50.0) -> Camera:
    """A camera that frames the scene's robust bounds, looking along +z of the world."""
    lo, hi = scene.robust_bounds()
    centre = (lo + hi) / 2
    radius = max(float(np.linalg.norm(hi - lo)) / 2, 1e-6)
    half = math.radians(fov_deg) / 2 * min(1.0, height / width)
    dist = radius / math.sin(half) if half > 0 else 2 * radius
    eye = centre - np.array([0.0, 0.0, dist])
    return look_at(eye, centre, width, height, fov_deg)
