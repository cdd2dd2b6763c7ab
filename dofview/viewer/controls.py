"""Camera controls of the viewer: orbit, pan and zoom around a pivot, and fly (move + look).

Pure numpy, no window: the viewer feeds it mouse deltas in pixels and key states, and asks it
for a :class:`~dofview.camera.Camera` at the window's image size. Conventions follow camera.py
(OpenCV: x right, y down, z forward; R maps world → camera, so its rows are the camera axes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dofview.camera import Camera

ORBIT_RAD_PER_PX = 0.005
LOOK_RAD_PER_PX = 0.003
ZOOM_PER_STEP = 0.85  # pivot distance factor per scroll step
MIN_POLE_ANGLE = math.radians(2.0)  # orbiting stops this close to straight up/down


def rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """(3, 3) rotation by ``angle`` radians about unit ``axis`` (right-handed, Rodrigues)."""
    x, y, z = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


def _orthonormal(R: np.ndarray) -> np.ndarray:
    """The rotation nearest to ``R`` (undoes drift after many small rotations)."""
    u, _, vt = np.linalg.svd(R)
    return u @ vt


@dataclass
class ViewControls:
    """A free camera: rotation, centre, pivot distance, world up and a reference focal length.

    Attributes:
        R: (3, 3) float64 world → camera rotation.
        centre: (3,) float64 camera centre, scene units.
        pivot_distance: distance from the centre to the orbit pivot along the view axis, scene units.
        up: (3,) float64 unit world direction shown as image-up (orbit yaw turns about it).
        ref_size: (width, height) of the frame the focal length below was given for.
        ref_fx: focal length in pixels for ``ref_size``; any window size shows at least that frame.
    """

    R: np.ndarray
    centre: np.ndarray
    pivot_distance: float
    up: np.ndarray
    ref_size: tuple[int, int]
    ref_fx: float

    @classmethod
    def from_camera(cls, camera: Camera, pivot_distance: float) -> "ViewControls":
        """Controls that start at ``camera``; image-up of that camera becomes the world up."""
        return cls(R=camera.R.copy(), centre=camera.centre.copy(), pivot_distance=max(float(pivot_distance), 1e-6),
                   up=-camera.R[1].copy(), ref_size=(camera.width, camera.height), ref_fx=float(camera.fx))

    @property
    def pivot(self) -> np.ndarray:
        """(3,) float64 world point orbited around, scene units."""
        return self.centre + self.pivot_distance * self.R[2]

    def focal_for(self, width: int, height: int) -> float:
        """Focal length (pixels) that fits the reference frame inside a ``width``×``height`` image."""
        return self.ref_fx * min(width / self.ref_size[0], height / self.ref_size[1])

    def camera(self, width: int, height: int, name: str = "") -> Camera:
        """The current view as a square-pixel, centred pinhole camera of the given size."""
        f = self.focal_for(width, height)
        return Camera(width, height, f, f, width / 2, height / 2, self.R.copy(), -self.R @ self.centre, name=name)

    # ---- rotations -------------------------------------------------------------------------
    def _turn(self, yaw: float, pitch: float, about: np.ndarray) -> None:
        """Yaw about world up and pitch about the camera's x axis, both around the point ``about``.

        Pitch is limited so the view axis never reaches the up direction (no flip over the pole).
        """
        fwd = self.R[2]
        angle_to_up = math.acos(float(np.clip(np.dot(fwd, self.up), -1.0, 1.0)))
        # a positive pitch tilts the view axis towards up
        pitch = float(np.clip(pitch, -(math.pi - MIN_POLE_ANGLE - angle_to_up), angle_to_up - MIN_POLE_ANGLE))
        q = rotation(self.up, yaw) @ rotation(self.R[0], pitch)
        self.centre = about + q @ (self.centre - about)
        self.R = _orthonormal(self.R @ q.T)

    def orbit(self, dx: float, dy: float) -> None:
        """Drag by (dx, dy) pixels: turn the camera around the pivot (the pivot stays in place).

        Dragging right swings the camera to the left around the pivot (the scene turns with the
        mouse); dragging down raises the camera so it looks down on the pivot.
        """
        self._turn(-dx * ORBIT_RAD_PER_PX, -dy * ORBIT_RAD_PER_PX, self.pivot)

    def look(self, dx: float, dy: float) -> None:
        """Mouse look by (dx, dy) pixels: turn the camera about its own centre (right looks right,
        down looks down)."""
        self._turn(-dx * LOOK_RAD_PER_PX, -dy * LOOK_RAD_PER_PX, self.centre.copy())

    # ---- translations ----------------------------------------------------------------------
    def pan(self, dx: float, dy: float, focal: float) -> None:
        """Drag by (dx, dy) pixels: slide the camera so the pivot plane follows the mouse.

        ``focal`` is the current focal length in pixels (a pixel at the pivot's depth spans
        pivot_distance / focal scene units).
        """
        scale = self.pivot_distance / focal
        self.centre = self.centre - scale * (dx * self.R[0] + dy * self.R[1])

    def zoom(self, steps: float) -> None:
        """Scroll by ``steps``: dolly towards (steps > 0) or away from the pivot, which stays put."""
        pivot = self.pivot
        self.pivot_distance = max(self.pivot_distance * ZOOM_PER_STEP ** steps, 1e-6)
        self.centre = pivot - self.pivot_distance * self.R[2]

    def fly(self, right: float, down: float, forward: float, distance: float) -> None:
        """Move ``distance`` scene units along the camera's (right, down, forward) direction mix.

        The direction (WASD/QE keys held) is normalised, so diagonals are not faster.
        """
        d = np.array([right, down, forward], np.float64)
        n = np.linalg.norm(d)
        if n > 0:
            self.centre = self.centre + distance * (self.R.T @ (d / n))
