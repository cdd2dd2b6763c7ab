"""Tone-mapping adaptation in the viewer: the adaptive operators' statistics, from GPU histograms of
each frame, smoothed in time like an eye (or locked, or pooled over the rig's views)."""

from __future__ import annotations

import numpy as np

from dofview.camera import Camera
from dofview.frame import RenderSettings
from dofview.rendering import Renderer
from dofview.tonemap import Operator, Tonemap
from dofview.tonemap.stats import Stats, StatsSmoother, cdf_domain


class ToneAdaptation:
    """The statistics an adaptive operator draws with: this frame's (:meth:`adapt`), smoothed with
    the measured frame interval (:attr:`smoother`), or locked."""

    def __init__(self) -> None:
        self.smoother = StatsSmoother()
        self.locked = False  # the panel's "lock adaptation" (ViewerSettings.stats_lock) as last applied
        self._frame_stats: Stats | None = None
        self._stats_time: float | None = None

    def reset(self) -> None:
        """Another scene: start from its first frame."""
        self.smoother.reset()

    def adapt(self, renderer: Renderer, tm: Tonemap, now: float, locked: bool, same_frame: bool = False) -> Stats | None:
        """This frame's statistics from ``renderer``'s targets (histograms only are read back),
        smoothed with the measured frame interval; None for the fixed operators. ``locked``: keep
        the smoothed statistics as they are. ``same_frame``: the targets hold the image the last
        statistics came from; once adaptation has settled they are reused (no histogram pass, no
        read-back and its GPU sync on idle frames)."""
        op = tm.operator
        if not op.adaptive:
            self._frame_stats = self._stats_time = None
            return None
        self.locked = locked
        state = self.smoother.state
        if (same_frame and self._frame_stats is not None and state is not None and not self.adapting
                and op.needs_cdf == (state.cdf is not None)):
            self._stats_time = now
            return state
        domain = cdf_domain(state) if op.needs_cdf and state is not None and state.cdf is not None else None
        self._frame_stats = renderer.frame_stats(op, domain)
        if op.needs_cdf != (state is not None and state.cdf is not None):
            self.smoother.reset()  # another operator's statistics: start from this frame
        dt = now - self._stats_time if self._stats_time is not None else 0.0
        self._stats_time = now
        self.smoother.locked = locked
        return self.smoother.update(self._frame_stats, dt)

    def lock_joint(self, renderer: Renderer, cameras: list[Camera], operator: Operator,
                   settings: RenderSettings) -> None:
        """``--stats joint``: statistics pooled over every view of ``cameras``, locked (no adaptation);
        the pooled renders replace ``renderer``'s targets."""
        from dofview.api import joint_stats

        self.smoother.state = joint_stats(renderer, cameras, operator, settings)
        self.locked = True

    @property
    def adapting(self) -> bool:
        """The smoothed statistics are still moving towards this frame's (more than 0.01 stop)."""
        s, f = self.smoother.state, self._frame_stats
        return (s is not None and f is not None and not self.locked
                and float(np.abs(s.scalars()[:6] - f.scalars()[:6]).max()) > 0.01)
