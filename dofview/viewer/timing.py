"""The viewer's frame times for its status line, every one from the same clock
(:func:`time.perf_counter`) and each a part of the frame it is shown with.

A frame runs from the start of one :meth:`~dofview.viewer.viewer.Viewer.frame` to the start of
the next: its work (input, a pass drawn into the renderer's targets or none, tone mapping, the
panel), the buffer swap and the wait for the next event. Its render part is the pass drawn in it
(:meth:`~dofview.viewer.model.ViewerModel.update`: the full frame or a preview, a thin-lens
refinement pass, or the pinhole frame the interaction budget times; the draw to ``ctx.finish``),
named, and none when the image was kept. The status shows the last complete frame, never a part
of one frame beside the whole of another (it showed ``frame 637.8 ms splat 725.6 ms``: the frame
before the splat's, and the splat time kept from whichever frame last drew), and it names the
pass (it showed ``splat 0.0 ms`` beside a 1.3 s frame of refinement).
"""

from __future__ import annotations

from collections import deque

HISTORY = 120  # frames in the status graph


class FrameTimes:
    """Frame periods and the pass drawn in each, milliseconds.

    Attributes:
        periods: the last :data:`HISTORY` complete frames' lengths (oldest first).
        render_ms: the pass the last complete frame drew (0: it drew none and kept the image).
        render_kind: what that pass drew ("depth layers", "per splat at 1/2", "thin-lens
            refinement", ...; "" when none).
    """

    def __init__(self) -> None:
        self.periods: deque[float] = deque(maxlen=HISTORY)
        self.render_ms = 0.0
        self.render_kind = ""
        self._start: float | None = None
        self._pass = ("", 0.0)

    def begin(self, now: float) -> None:
        """A frame starts at ``now`` (perf_counter seconds): the one before it is complete."""
        if self._start is not None:
            self.periods.append((now - self._start) * 1e3)
            self.render_kind, self.render_ms = self._pass
        self._start, self._pass = now, ("", 0.0)

    def rendered(self, kind: str, ms: float) -> None:
        """The frame under way drew a pass of ``kind`` taking ``ms`` milliseconds."""
        self._pass = (kind, ms)

    @property
    def frame_ms(self) -> float:
        """The last complete frame's length (0 before one is)."""
        return self.periods[-1] if self.periods else 0.0

    def status(self, sort_ms: float) -> str:
        """The status, two lines: the last frame and the pass drawn in it, then the last depth sort
        (``sort_ms``: the quad backend sorts on a thread beside the frames, so it is no part of
        one; the compute backend sorts within the splatting pass and reports none)."""
        part = f"{self.render_kind} {self.render_ms:.1f} ms" if self.render_kind else "image kept"
        return f"frame {self.frame_ms:.1f} ms ({part})\nlast sort {sort_ms:.1f} ms"
