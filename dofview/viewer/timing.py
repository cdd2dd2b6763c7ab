"""The viewer's frame times for its status line, every one from the same clock
(:func:`time.perf_counter`) and each a part of the frame it is shown with.

A frame runs from the start of one :meth:`~dofview.viewer.viewer.Viewer.frame` to the start of
the next: its work (input, the splatting pass or a refinement pass, tone mapping, the panel), the
buffer swap and the wait for the next event. Its splat part is the splatting pass drawn in it
(:meth:`~dofview.viewer.model.ViewerModel.update`: the draw to ``ctx.finish``), 0 when the image
was kept. The status shows the last complete frame, never a part of one frame beside the whole
of another (it showed ``frame 637.8 ms splat 725.6 ms``: the frame before the splat's, and the
splat time kept from whichever frame last drew).
"""

from __future__ import annotations

from collections import deque

HISTORY = 120  # frames in the status graph


class FrameTimes:
    """Frame periods and their splat parts, milliseconds.

    Attributes:
        periods: the last :data:`HISTORY` complete frames' lengths (oldest first).
        splat_ms: the splatting pass of the last complete frame (0: it drew none).
    """

    def __init__(self) -> None:
        self.periods: deque[float] = deque(maxlen=HISTORY)
        self.splat_ms = 0.0
        self._start: float | None = None
        self._splat = 0.0

    def begin(self, now: float) -> None:
        """A frame starts at ``now`` (perf_counter seconds): the one before it is complete."""
        if self._start is not None:
            self.periods.append((now - self._start) * 1e3)
            self.splat_ms = self._splat
        self._start, self._splat = now, 0.0

    def splatted(self, ms: float) -> None:
        """The frame under way drew a splatting pass of ``ms`` milliseconds."""
        self._splat += ms

    @property
    def frame_ms(self) -> float:
        """The last complete frame's length (0 before one is)."""
        return self.periods[-1] if self.periods else 0.0

    def status(self, sort_ms: float) -> str:
        """The status line: the last frame and its splat part, and the last depth sort
        (``sort_ms``: the quad backend sorts on a thread beside the frames, so it is no part of
        one; the compute backend sorts within the splatting pass and reports none)."""
        return f"frame {self.frame_ms:.1f} ms (splat {self.splat_ms:.1f} ms)  last sort {sort_ms:.1f} ms"
