"""What the viewer's lens and image panels hold, and the render objects built from it.

Kept apart from the window so the mapping panel values → Lens / Tonemap / RenderSettings is the
same one the headless renderer gets, and can be tested without a display.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

from dofview.camera import Camera
from dofview.frame import RenderSettings
from dofview.lens import Lens, LensRequest, shutter_ev
from dofview.tonemap import OPERATORS, Operator, Tonemap, operator_from_dict

FOCUS_PULL_S = 0.15  # duration of a smooth focus pull
START_COC_PX = 0.5  # without --aperture the first frame blurs nothing by a pixel: sharp, yet the slider is live
MAX_COC_PX = 30.0  # the aperture slider ends where the largest blur in view reaches this radius


@dataclass
class ViewerSettings:
    """Panel values. Distances in scene units, aperture strength A in px·(scene unit) on the image as
    drawn (``--aperture``/``--blur`` are resolved to it at the start; "copy as command" turns it
    back into a strength at the command's reference width, options.render_command_line).

    With ``physical`` on, the aperture comes from focal length, f-number, sensor width and the
    scene scale (Cinematic Gaussians Eq. 3) instead of ``aperture``. With ``exposure_follows_aperture``
    on, exposure is EV + log2(t/N²) stops (the factor t/N² of Eq. 7), so stopping down darkens the
    image as a real lens does.
    """

    focus: float = 1.0
    aperture: float = 0.0
    dof_enabled: bool = True  # the panel's depth-of-field switch (off: a pinhole)
    physical: bool = False
    focal_mm: float = 50.0
    fnumber: float = 2.8
    sensor_mm: float = 36.0
    units_per_metre: float = 1.0
    ev: float = 0.0
    gamma: float = 2.2
    exposure_follows_aperture: bool = False
    shutter_s: float = 1.0 / 8.0
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tonemap_operator: str = "clip"  # a key of dofview.tonemap.OPERATORS
    tonemap_params: dict[str, float] = field(default_factory=dict)  # its parameters (missing: defaults)
    tonemap_auto: bool = False  # the operator follows each opened scene's colour space until one is picked
    stats_lock: bool = False  # freeze the adaptive operators' smoothed statistics
    colour_space: str = "srgb"
    focus_aid: bool = False
    smooth_focus: bool = True
    lens_samples_max: int = 256  # passes of the last stage the thin lens is refined to while still (0: off)
    render: RenderSettings = field(default_factory=RenderSettings)

    def lens_request(self) -> LensRequest:
        """The panel's lens as a request: the physical lens when on, else the strength A as drawn."""
        if self.physical:
            return LensRequest(fnumber=self.fnumber, focal_mm=self.focal_mm, sensor_mm=self.sensor_mm,
                               units_per_metre=self.units_per_metre)
        return LensRequest(aperture=self.aperture, sensor_mm=self.sensor_mm, units_per_metre=self.units_per_metre)

    def lens(self, camera: Camera) -> Lens:
        """The lens for ``camera`` (its f_x turns a physical lens into an aperture strength)."""
        if not self.dof_enabled:
            return Lens(self.focus, 0.0)
        request = self.lens_request()
        if request.physical is not None:
            # a physical lens cannot focus inside its focal length: hold the focus just beyond it
            return request.lens(camera, max(self.focus, request.physical.focal_units * 1.001))
        return Lens(self.focus, self.aperture)  # A as drawn, whatever the camera's reference width

    def tonemap(self) -> Tonemap:
        ev = self.ev
        if self.exposure_follows_aperture and self.physical:
            ev += shutter_ev(self.shutter_s, self.fnumber)
        return Tonemap(exposure=ev, gamma=self.gamma, background=self.background, operator=self.operator())

    def operator(self) -> Operator:
        """The tone-mapping operator with the panel's parameters (those it does not have are dropped)."""
        names = {f.name for f in fields(OPERATORS[self.tonemap_operator])}
        return operator_from_dict({"operator": self.tonemap_operator,
                                   **{k: v for k, v in self.tonemap_params.items() if k in names}})


class FocusPull:
    """A focus change eased over :data:`FOCUS_PULL_S` seconds, in inverse depth (how blur changes).

    ``start(current, target, now)`` begins a pull; ``value(now)`` is the focus at time ``now``
    (seconds), reaching ``target`` exactly at the end; ``active`` says whether one is running.
    """

    def __init__(self, duration: float = FOCUS_PULL_S) -> None:
        self.duration = duration
        self._from = self._to = 1.0
        self._t0 = -math.inf
        self.target: float | None = None

    def start(self, current: float, target: float, now: float) -> None:
        self._from, self._to, self._t0, self.target = 1.0 / current, 1.0 / target, now, target

    @property
    def active(self) -> bool:
        return self.target is not None

    def value(self, now: float) -> float:
        """The focus distance at ``now``; finishing the pull clears :attr:`active`."""
        if self.target is None:
            raise RuntimeError("no focus pull running")
        s = min(max((now - self._t0) / self.duration, 0.0), 1.0)
        if s >= 1.0:
            target, self.target = self.target, None
            return target
        ease = s * s * (3.0 - 2.0 * s)  # smoothstep: starts and stops gently
        return 1.0 / (self._from + (self._to - self._from) * ease)
