"""The viewer's interaction budget: while the camera or the lens moves, frames cost no more than
the pinhole frame × :data:`BUDGET_FACTOR` (measured), drawn by the best preview the measured costs
allow; once the view rests for :data:`STILL_AFTER_S`, the full frame (and then the refinement).

A :class:`Preview` is a depth-of-field mode at an internal resolution (the image shown is scaled
up to the window). The ladder of previews runs from the best to the cheapest, ordered by their
error against the still frame as measured on the shared scenes (``python -m dofview.bench.preview``,
docs/BENCHMARKS.md). Costs are measured as the frames are drawn: a rung never drawn is tried once,
the rungs already measured over the budget are skipped. The pinhole frame is timed by the viewer's
pinhole passes and, when that timing is stale, once the view rests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from dofview.camera import Camera
from dofview.frame import RenderSettings
from dofview.lens import Lens

BUDGET_FACTOR = 1.2
STILL_AFTER_S = 0.12  # a view unchanged this long is still (a slider held between two drags is not)
PINHOLE_STALE_S = 10.0  # a pinhole frame timed this long ago is timed again once the view rests
SMOOTHING = 0.5  # weight of a new cost measurement against the ones before


@dataclass(frozen=True)
class Preview:
    """A way to draw the frame: the depth-of-field mode (``RenderSettings.dof``) at 1/``scale`` of
    the image's width and height."""

    dof: str
    scale: int = 1

    def view(self, camera: Camera, lens: Lens, settings: RenderSettings) -> tuple[Camera, Lens, RenderSettings]:
        """Camera, lens and settings that draw this preview of a frame: the camera resized (its
        focal length with it), the aperture strength A scaled as the width (A = f_x·D), so each
        point's blur keeps its size relative to the image."""
        settings = settings if settings.dof == self.dof else replace(settings, dof=self.dof)
        if self.scale == 1:
            return camera, lens, settings
        w, h = max(1, camera.width // self.scale), max(1, camera.height // self.scale)
        return camera.resized(w, h), replace(lens, aperture=lens.aperture * w / camera.width), settings

    def __str__(self) -> str:
        name = {"sliced": "depth layers", "splat": "per splat"}.get(self.dof, self.dof)
        return name if self.scale == 1 else f"{name} at 1/{self.scale}"


LADDERS: dict[str, tuple[Preview, ...]] = {
    "sliced": (Preview("sliced"), Preview("splat"), Preview("sliced", 2), Preview("splat", 2),
               Preview("sliced", 4), Preview("splat", 4)),
    "splat": (Preview("splat"), Preview("splat", 2), Preview("splat", 4)),
}
"""Per depth-of-field mode, the previews from the best (the full frame) to the cheapest."""


class InteractionBudget:
    """Which preview to draw while the view moves (testable without a window or a GPU: it is told
    the states and the times drawn).

    Each frame :meth:`moving` is given the frame's state (anything whose change redraws) and the
    time; :meth:`choose` then names the preview for the frame, and :meth:`record` /
    :meth:`record_pinhole` take the measured costs (ms)."""

    def __init__(self, factor: float = BUDGET_FACTOR, still_after_s: float = STILL_AFTER_S) -> None:
        self.factor, self.still_after_s = factor, still_after_s
        self.costs: dict[Preview, float] = {}
        self.pinhole_ms: float | None = None
        self._pinhole_at = -math.inf
        self._state: object = None
        self._changed_at = -math.inf

    @property
    def budget_ms(self) -> float | None:
        """The most a frame may cost while the view moves, ms (None until a pinhole frame was timed)."""
        return None if self.pinhole_ms is None else self.factor * self.pinhole_ms

    def moving(self, state: object, now: float) -> bool:
        """Whether the view is moving at ``now`` (s): ``state`` changed within :attr:`still_after_s`."""
        if state != self._state:
            self._state, self._changed_at = state, now
        return now - self._changed_at < self.still_after_s

    def choose(self, dof: str, moving: bool) -> Preview:
        """The preview to draw: the full frame when still or before any pinhole frame was timed;
        while moving the best rung of ``dof``'s ladder not measured over the budget (one never
        measured is tried), else the cheapest."""
        ladder = LADDERS[dof]
        budget = self.budget_ms
        if not moving or budget is None:
            return ladder[0]
        for p in ladder:
            cost = self.costs.get(p)
            if cost is None or cost <= budget:
                return p
        return ladder[-1]

    def record(self, preview: Preview, ms: float) -> None:
        """The time a draw of ``preview`` took (ms), smoothed with the ones before."""
        old = self.costs.get(preview)
        self.costs[preview] = ms if old is None else SMOOTHING * ms + (1 - SMOOTHING) * old

    def record_pinhole(self, ms: float, now: float) -> None:
        """The time a pinhole frame of the current view took (ms) at ``now`` (s)."""
        self.pinhole_ms = ms if self.pinhole_ms is None else SMOOTHING * ms + (1 - SMOOTHING) * self.pinhole_ms
        self._pinhole_at = now

    def pinhole_due(self, now: float) -> bool:
        """The pinhole frame should be timed again at ``now`` (none yet, or stale): the viewer does
        it while the view rests, where it holds up no motion."""
        return now - self._pinhole_at >= PINHOLE_STALE_S

    def pinhole_stale(self, scale: float = 1.0) -> None:
        """The scene drawn changed: the pinhole frame's cost is taken as ``scale`` times the last
        (the ratio of Gaussians drawn, as a vertex-bound frame scales) until it is timed again."""
        if self.pinhole_ms is not None:
            self.pinhole_ms *= scale
        self._pinhole_at = -math.inf

    def forget(self) -> None:
        """Drop every cost (another scene: the measured ones no longer hold)."""
        self.costs.clear()
        self.pinhole_ms, self._pinhole_at = None, -math.inf
