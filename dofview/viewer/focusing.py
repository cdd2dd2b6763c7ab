"""The viewer's lens, without a window: focus (click, auto, typed) and focus pulls, the lens a view
opens with, and the pinhole passes both measure from (the depths in view, which scale the sliders,
and the pinhole frame's time, which sets the interaction budget). Built on
:class:`~dofview.viewer.views.ViewerViews`; :class:`~dofview.viewer.model.ViewerModel` adds the frames.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import moderngl

from dofview.camera import Camera
from dofview.frame import Frame
from dofview.lens import BlurSpec, Lens, aperture_for_blur
from dofview.rendering.focus import auto_focus, depth_at, depth_range
from dofview.viewer.interaction import InteractionBudget
from dofview.viewer.settings import START_COC_PX, FocusPull, ViewerSettings
from dofview.viewer.views import ViewerViews


class ViewerLens(ViewerViews):
    """Focus and the lens of the viewer (see the module docstring); arguments as :class:`ViewerViews`."""

    def __init__(self, ctx: moderngl.Context, image_size: Callable[[], tuple[int, int]], settings: ViewerSettings,
                 cameras: list[Camera], raster: str = "auto", budget: int | None = None, lod: int | None = None) -> None:
        super().__init__(ctx, image_size, settings, cameras, raster, budget, lod)
        self.pull = FocusPull()
        self.interaction = InteractionBudget()
        self.depth_span = (1.0, 1.0)  # near and far depth in view (2nd/98th percentile), scene units
        # the lens a view starts with (R, U, N re-derive it): the --focus / --aperture given for the
        # scene opened first, None for the first-frame rule (see frame_lens)
        self.start_focus: float | None = None
        self.start_aperture: float | None = None
        self.start_blur: BlurSpec | None = None  # --blur: resolved again on each view's own depths
        self._drawn_key: tuple | None = None  # what the targets hold (the model's frames)
        self._pinhole_view: tuple | None = None  # the view whose pinhole frame was timed last
        self.passes = 0  # passes drawn into the targets, of any kind
        self.last_pass = ("", 0.0)  # the last of them: what it drew, and its ms (to ctx.finish)

    def _loaded(self) -> None:
        self.start_focus = self.start_aperture = self.start_blur = None  # the command line's lens was for the first scene's scale
        self.frame_lens()

    # ---- focus and the lens a view opens with ------------------------------------------------
    def set_focus(self, focus: float, smooth: bool | None = None) -> None:
        """Focus at ``focus`` scene units, eased over 0.15 s when smooth focus is on."""
        if smooth if smooth is not None else self.settings.smooth_focus:
            self.pull.start(self.settings.focus, focus, time.perf_counter())
        else:
            self.pull.target = None
            self.settings.focus = focus

    def depth_under(self, x: float, y: float) -> float | None:
        """Depth (scene units) under image pixel (x, y) (framebuffer pixels, top-left origin), from
        the renderer's α-weighted inverse depth of a pinhole pass (a blurred pass would mix objects)."""
        return depth_at(self.pinhole_pass(sort=False), x, y)

    def focus_at(self, x: float, y: float) -> float | None:
        """Click-to-focus at image pixel (x, y); returns the depth, or None over empty space."""
        depth = self.depth_under(x, y)
        if depth is None:
            self.message = "nothing under the cursor to focus on"
        else:
            self.set_focus(depth)
            self.message = f"focus {depth:.4g} (pixel {x:.0f}, {y:.0f})"
        return depth

    def auto_focus(self) -> None:
        """Focus at the median depth under the image centre (as ``dofview render --focus auto``)."""
        depth = auto_focus(self.pinhole_pass(sort=True))
        self.settings.focus = depth if depth is not None else self.controls.pivot_distance
        self.pull.target = None

    def frame_lens(self) -> None:
        """The lens a view opens with (its first frame is sharp): focus on what is under the image
        centre, or at :attr:`start_focus`; aperture :attr:`start_aperture`, or the blur
        :attr:`start_blur` on this view's depths, else (unless the physical lens gives it) the one
        whose largest blur in view is ``START_COC_PX`` pixels.

        Measures the depths in view on the way (:attr:`depth_span`, which scales the sliders).
        """
        if self.start_focus is None:
            self.auto_focus()
        else:
            self.pinhole_pass(sort=True)
            self.set_focus(self.start_focus, smooth=False)
        if self.start_aperture is not None:
            self.settings.aperture = self.start_aperture
        elif self.start_blur is not None:
            cam = self.camera()
            self.settings.aperture = self.start_blur.aperture(cam.width, cam.ref_width, self.settings.focus,
                                                              self.depth_span)
        elif not self.settings.physical:
            self.settings.aperture = self.aperture_for_blur(START_COC_PX)

    def pinhole_pass(self, sort: bool) -> Frame:
        """Draw and read back a pinhole pass of the current view (sorted first if ``sort``, else with
        the order the view has, which may be on its way), and take the depth range in view from it
        (:attr:`depth_span`, which scales the sliders) and its time (the interaction budget's)."""
        camera = self.camera()
        if sort:
            self.renderer.sort(camera)
        self._time_pinhole(camera)
        frame = self.renderer.read()
        span = depth_range(frame)
        if span is not None:
            self.depth_span = span
        return frame

    def _time_pinhole(self, camera: Camera) -> None:
        t0 = time.perf_counter()
        self.renderer.draw(camera, Lens(1.0, 0.0), self.settings.render)
        self.ctx.finish()
        self._drew("pinhole, timed", (time.perf_counter() - t0) * 1e3)
        self.interaction.record_pinhole(self.last_pass[1], time.perf_counter())
        self._pinhole_view = self._view_of(camera)
        self._drawn_key = None  # the targets now hold the pinhole pass

    def _drew(self, kind: str, ms: float) -> None:
        self.passes += 1
        self.last_pass = (kind, ms)

    def _view_of(self, camera: Camera) -> tuple:
        """What a pinhole frame's cost depends on: the view, the image size and the Gaussians drawn."""
        return camera.view_key(), camera.width, camera.height, self.scene.count

    @property
    def focus_range(self) -> tuple[float, float]:
        """The focus slider's ends: half the nearest to twice the farthest depth in view (last measured)."""
        near, far = self.depth_span
        return min(0.5 * near, self.settings.focus), max(2.0 * far, self.settings.focus)

    def aperture_for_blur(self, radius_px: float) -> float:
        """Aperture A at which the largest blur in view (nearest or farthest depth, at the current
        focus) has a radius of ``radius_px`` pixels (:func:`dofview.lens.aperture_for_blur`)."""
        near, far = self.depth_span
        return aperture_for_blur(radius_px, self.settings.focus, near, far)
