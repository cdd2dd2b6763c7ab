"""The viewer's model: everything it shows, without a window — the scene and its renderer, the
cameras of the rig and the up axis, the view controls, focus and focus pulls, the lens and image
settings, the sort, progressive refinement and tone-mapping adaptation, saving and the equivalent
command line. viewer.py puts it in a window; a test drives it headless (tests/test_viewer_model.py).

:meth:`ViewerModel.update` brings the renderer's targets up to date for one frame: it advances a
focus pull, asks the renderer for the current view's order (the quad backend sorts in the
background and draws with the last order meanwhile), splats again only when the camera, lens or
splatting settings changed, and otherwise adds a pinhole pass of the thin lens while the view rests.
Exposure, gamma, background and the focus aid only re-run the tonemap (the view's business).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import moderngl
import numpy as np

from dofview.api import save_render
from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.frame import Frame
from dofview.framing import (
    UP_AXES,
    UpGuess,
    axis_vector,
    extent,
    guess_up,
    nearest_axis,
    overview_camera,
    rig_centre,
    rig_up,
)
from dofview.io.cameras import load_cameras_json
from dofview.lens import BlurSpec, Lens, aperture_for_blur
from dofview.options import render_command_line
from dofview.rendering import Renderer, get_backend
from dofview.rendering.focus import auto_focus, depth_at, depth_range
from dofview.rendering.progressive import ProgressiveLens, next_stage
from dofview.scene import GaussianScene
from dofview.tonemap import Tonemap
from dofview.tonemap.stats import Stats, StatsSmoother, cdf_domain
from dofview.viewer.controls import ViewControls
from dofview.viewer.loader import SceneLoad
from dofview.viewer.settings import START_COC_PX, FocusPull, ViewerSettings

COUNT_EVERY_S = 0.5  # how often the drawn-Gaussian counter is read back (it costs a GPU sync)


class ViewerModel:
    """The viewer's state and its actions (see the module docstring). The window (viewer.py), its
    panel, mouse and keys and the script drive it through these public attributes and methods.

    Args:
        ctx: the GL context to render with (the window's, or a headless one).
        image_size: gives the (width, height) in pixels of the image the camera renders, now.
        raster: renderer backend name (:data:`dofview.rendering.BACKENDS`, or ``"auto"``).
    """

    def __init__(self, ctx: moderngl.Context, image_size: Callable[[], tuple[int, int]], scene: GaussianScene,
                 scene_path: Path, settings: ViewerSettings, camera: Camera | None, cameras: list[Camera],
                 up: UpGuess | None = None, raster: str = "auto") -> None:
        self.ctx = ctx
        self._image_size = image_size
        self.settings = settings
        self.cameras = cameras
        self.raster = raster
        self.view_index: int | None = None
        self.pull = FocusPull()
        self.smoother = StatsSmoother()  # adaptive tone mapping: statistics smoothed in time
        self._frame_stats: Stats | None = None
        self._stats_time: float | None = None
        self.loading: SceneLoad | None = None
        self.message = ""  # last status line (saved file, copied command)
        self.error = ""  # last error (failed load or save), shown in red until the next action
        self.fly_speed = 1.0  # scene units per second
        self.render_ms = 0.0
        self.splat_draws = 0  # splatting passes shown (exposure, gamma, background, focus aid add none)
        self._last_count = -math.inf
        self._drawn_key: tuple | None = None
        self.generation = 0  # scenes shown so far
        self.depth_span = (1.0, 1.0)  # near and far depth in view (2nd/98th percentile), scene units
        # the overview camera (R, U, a scene opened without cameras) frames the scene for this
        # width, height (pixels) and horizontal field of view (degrees); app.py sets the window's
        self.framing = (800, 600, 50.0)
        # the lens a view starts with (R, U, N re-derive it): the --focus / --aperture given for the
        # scene opened first, None for the first-frame rule (see frame_lens)
        self.start_focus: float | None = None
        self.start_aperture: float | None = None
        self.start_blur: BlurSpec | None = None  # --blur: resolved again on each view's own depths
        self.renderer: Renderer | None = None
        self.set_scene(scene, scene_path, camera, up)

    # ---- scene and views -------------------------------------------------------------------
    def set_scene(self, scene: GaussianScene, path: Path, camera: Camera | None = None, up: UpGuess | None = None) -> None:
        """Show ``scene``: upload it, start at ``camera`` (default: view 0 of :attr:`cameras`, else a
        camera framing the scene from the ``up`` given or guessed) and sort once up front.

        The new scene is uploaded before the old one is released, so a failed upload keeps it. The
        renderer is new, so is its draw order: the first frame sorts up front.
        """
        renderer = get_backend(self.raster, scene, ctx=self.ctx)
        if self.renderer is not None:
            self.progressive.release()
            self.renderer.release()
        self.renderer = renderer
        self.progressive = ProgressiveLens(renderer)  # the thin lens refined while still
        self.scene, self.scene_path = scene, Path(path)
        self.generation += 1
        self.smoother.reset()
        self.settings.colour_space = scene.colour_space
        if self.settings.tonemap_auto:  # --tonemap auto: each scene opens with its colour space's operator
            from dofview.tonemap import default_operator

            self.settings.tonemap_operator, self.settings.tonemap_params = default_operator(scene.colour_space), {}
        self.centre, self.radius = extent(scene)
        self.fly_speed = 0.5 * self.radius
        self.view_index = None
        if self.cameras:
            self._use_rig()
        else:
            guess = up or guess_up(scene)
            self.up_label, self.up = guess.nearest_axis, guess.vector
            self.message = f"up {guess.label} ({guess.reason}); U cycles"
        if camera is None and self.cameras:
            camera, self.view_index = self.cameras[0], 0
        self._set_controls(camera or self._overview())
        self._drawn_key = None
        self._last_count = -math.inf  # count the new scene's first frame

    def _use_rig(self) -> None:
        """Orbit around the point nearest to all training views' axes, with their mean up."""
        self.up = rig_up(self.cameras)
        self.up_label = nearest_axis(self.up)
        centre = rig_centre(self.cameras)
        if centre is not None:
            self.centre = centre

    def _set_controls(self, camera: Camera) -> None:
        fwd = camera.forward
        pivot = float(np.dot(self.centre - camera.centre, fwd))
        self.controls = ViewControls.from_camera(camera, pivot if pivot > 0.05 * self.radius else self.radius)
        self.controls.up = self.up.copy()

    def _overview(self) -> Camera:
        w, h, fov = self.framing
        return overview_camera(self.scene, w, h, fov, up=self.up)

    def reset_view(self) -> None:
        """Back to the camera that frames the whole scene, with the lens it opens with."""
        self.view_index = None
        self._set_controls(self._overview())
        self.frame_lens()

    def cycle_up(self) -> None:
        """Take the next world up of :data:`UP_AXES` and frame the scene from it (the U key)."""
        self.up_label = UP_AXES[(UP_AXES.index(self.up_label) + 1) % len(UP_AXES)]
        self.up = axis_vector(self.up_label)
        self.reset_view()
        self.message = f"up {self.up_label} (U cycles)"

    def set_view(self, index: int) -> None:
        """Jump to camera ``index`` of cameras.json (wrapping around), with the lens it opens with."""
        if not self.cameras:
            return
        self.view_index = index % len(self.cameras)
        self._set_controls(self.cameras[self.view_index])
        self.frame_lens()

    def step_view(self, delta: int) -> None:
        """Next (delta 1) or previous (-1) view; from a free camera, the first or the last."""
        if self.view_index is None:
            self.set_view(0 if delta > 0 else -1)
        else:
            self.set_view(self.view_index + delta)

    def open_file(self, path: str | Path) -> None:
        """Start loading a scene (in the background) or, for a .json file, a set of cameras."""
        path = Path(path).expanduser()
        self.error = ""
        if path.suffix.lower() == ".json" and path.name.lower() != "meta.json":  # meta.json: a SOG scene
            try:
                self.cameras = load_cameras_json(path)
            except DofviewError as e:
                self.error = str(e)
                return
            self.message = f"{len(self.cameras)} cameras from {path.name}"
            self._use_rig()
            self.set_view(0)
            return
        self.loading = SceneLoad(path)

    def poll(self) -> None:
        """Take a finished background load (at the start of a frame)."""
        if self.loading is not None and self.loading.done:
            self._finish_load()

    def _finish_load(self) -> None:
        load, self.loading = self.loading, None
        if load.error:
            self.error = load.error  # the current scene stays
            return
        previous, self.cameras = self.cameras, load.cameras  # the old ones belonged to the previous scene
        try:
            self.set_scene(load.scene, load.path)
        except (DofviewError, moderngl.Error) as e:  # e.g. too large for this GPU's memory
            self.cameras = previous
            self.error = f"{load.path}: cannot show this scene ({e})"
            return
        self.message = (f"loaded {load.path.name}: {load.scene.count:,} Gaussians in {load.elapsed:.1f} s; "
                        + (load.found or self.message))
        self.start_focus = self.start_aperture = self.start_blur = None  # the command line's lens was for the first scene's scale
        self.frame_lens()

    # ---- the current image -----------------------------------------------------------------
    @property
    def image_size(self) -> tuple[int, int]:
        """(width, height) in pixels of the image (the window's image area left of the panel)."""
        return self._image_size()

    def camera(self) -> Camera:
        w, h = self.image_size
        name = self.cameras[self.view_index].name if self.view_index is not None else ""
        return self.controls.camera(w, h, name)

    def lens(self, camera: Camera | None = None) -> Lens:
        return self.settings.lens(camera or self.camera())

    def command_line(self) -> str:
        camera = self.camera()
        return render_command_line(str(self.scene_path), camera, self.lens(camera), self.settings.tonemap(),
                                   self.settings.render, self.settings.colour_space)

    # ---- actions ---------------------------------------------------------------------------
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
        (:attr:`depth_span`, which scales the sliders)."""
        camera = self.camera()
        if sort:
            self.renderer.sort(camera)
        self.renderer.draw(camera, Lens(1.0, 0.0), self.settings.render)
        frame = self.renderer.read()
        self._drawn_key = None  # the targets now hold the pinhole pass
        span = depth_range(frame)
        if span is not None:
            self.depth_span = span
        return frame

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

    def save(self, path: str | Path, png: bool) -> None:
        """Write the current view as EXR (and PNG beside it if ``png``), exactly as ``dofview render`` would."""
        out = Path(path).expanduser()
        self.error = ""
        try:
            if out.suffix.lower() != ".exr":
                raise DofviewError(f"{out}: output must be an .exr file")
            camera = self.camera()
            save_render(self.renderer, camera, self.lens(camera), self.settings.tonemap(), self.settings.render,
                        str(self.scene_path), out, out.with_suffix(".png") if png else None,
                        lens_info=self.settings.lens_request().to_dict(),
                        stats=self.smoother.state if self.settings.tonemap().operator.adaptive else None)
        except DofviewError as e:
            self.error = str(e)
            return
        finally:
            self._drawn_key = None
        self.message = f"saved {out}" + (" and .png" if png else "")

    # ---- one frame -------------------------------------------------------------------------
    def _state_key(self, camera: Camera, lens: Lens) -> tuple:
        return (camera.view_key(), camera.width, camera.height, camera.fx, lens, self.settings.render,
                self.settings.colour_space)

    def update(self, now: float) -> bool:
        """Bring the renderer's targets up to date for this frame: splat if anything the splats depend
        on changed, else add a pass of the thin lens while the view rests. Returns whether the targets
        hold the same image as the last frame's (so the display may keep what it derived from it)."""
        if self.pull.active:
            self.settings.focus = self.pull.value(now)
        camera = self.camera()
        lens = self.lens(camera)
        self.scene.colour_space = self.settings.colour_space  # the panel's choice; the renderer reads the scene's
        if self.renderer.request_order(camera):
            self._drawn_key = None  # a background sort finished: draw with its order
        state = self._state_key(camera, lens)
        drawn = state == self._drawn_key  # the targets already hold this frame
        if not drawn:
            count = now - self._last_count >= COUNT_EVERY_S
            t0 = time.perf_counter()
            self.renderer.draw(camera, lens, self.settings.render, count=count)
            self.ctx.finish()
            self.splat_draws += 1
            self.render_ms = (time.perf_counter() - t0) * 1e3
            if count:
                self._last_count = now
            self._drawn_key = state
            # the single-pass image is kept only where refinement can follow (it copies two float targets)
            self.progressive.restart(keep_single=lens.aperture > 0 and self.settings.lens_samples_max > 0)
        elif 0 < self.progressive.samples < self.settings.lens_samples_max and not self.busy:
            # still: one more pass of the next stage, the last complete stage staying on screen;
            # the first refinement (2 passes) is drawn whole, so the second still frame shows it
            stage = next_stage(self.progressive.samples, self.settings.lens_samples_max)
            while self.progressive.add(camera, lens, self.settings.render, stage) != stage and stage == 2:
                pass
            self.progressive.show()
            drawn = False  # the targets now hold the refined image
        return drawn

    def adapt(self, tm: Tonemap, now: float, same_frame: bool = False) -> Stats | None:
        """This frame's statistics from the GPU (histograms only are read back), smoothed with the
        measured frame interval; None for the fixed operators. ``same_frame``: the targets hold
        the image the last statistics came from; once adaptation has settled they are reused
        (no histogram pass, no read-back and its GPU sync on idle frames)."""
        op = tm.operator
        if not op.adaptive:
            self._frame_stats = self._stats_time = None
            return None
        state = self.smoother.state
        if (same_frame and self._frame_stats is not None and state is not None and not self.adapting
                and op.needs_cdf == (state.cdf is not None)):
            self._stats_time = now
            return state
        domain = cdf_domain(state) if op.needs_cdf and state is not None and state.cdf is not None else None
        self._frame_stats = self.renderer.frame_stats(op, domain)
        if op.needs_cdf != (state is not None and state.cdf is not None):
            self.smoother.reset()  # another operator's statistics: start from this frame
        dt = now - self._stats_time if self._stats_time is not None else 0.0
        self._stats_time = now
        self.smoother.locked = self.settings.stats_lock
        return self.smoother.update(self._frame_stats, dt)

    def lock_joint_stats(self) -> None:
        """``--stats joint``: statistics pooled over every view of cameras.json, locked (no adaptation)."""
        from dofview.api import joint_stats

        self.smoother.state = joint_stats(self.renderer, self.cameras, self.settings.operator(), self.settings.render)
        self.settings.stats_lock = True
        self._drawn_key = None  # the pooled renders replaced the targets

    @property
    def adapting(self) -> bool:
        """The smoothed statistics are still moving towards this frame's (more than 0.01 stop)."""
        s, f = self.smoother.state, self._frame_stats
        return (s is not None and f is not None and not self.settings.stats_lock
                and float(np.abs(s.scalars()[:6] - f.scalars()[:6]).max()) > 0.01)

    @property
    def busy(self) -> bool:
        """Work in flight that will change the image: a load, a sort, a focus pull or adaptation."""
        return self.loading is not None or self.renderer.sort_pending or self.pull.active or self.adapting

    @property
    def settled(self) -> bool:
        """The image shows the current state with the order sorted for the current view."""
        return not self.busy and self._drawn_key is not None

    def report(self) -> dict:
        """The state as plain data (the script's ``report`` action writes it as JSON, with the window's)."""
        camera = self.camera()
        lens = self.lens(camera)
        tm = self.settings.tonemap()
        return {
            "scene": str(self.scene_path), "count": self.scene.count, "generation": self.generation,
            "camera": {**camera.to_dict(), "name": camera.name},
            "lens": lens.to_dict(),
            "tonemap": {"exposure": tm.exposure, "gamma": tm.gamma, "background": list(tm.background),
                        "operator": tm.operator.name, "params": tm.operator.params(),
                        "stats": json.loads(self.smoother.state.to_json()) if self.smoother.state is not None
                        and tm.operator.adaptive else None, "locked": self.settings.stats_lock},
            "render": self.settings.render.to_dict(),
            "colour_space": self.settings.colour_space, "focus_aid": self.settings.focus_aid,
            "focus_pull_target": self.pull.target, "pivot": self.controls.pivot.tolist(),
            "up": self.up.tolist(), "up_label": self.up_label,
            "depth_span": list(self.depth_span), "view_index": self.view_index, "views": len(self.cameras),
            "drawn": self.renderer.stats.drawn, "total": self.renderer.stats.total,
            "sort_ms": self.renderer.stats.sort_ms, "sort_requests": self.renderer.stats.sort_requests,
            "message": self.message, "error": self.error, "command": self.command_line(),
            "splat_draws": self.splat_draws, "lens_samples": self.progressive.samples,
        }

    def close(self) -> None:
        self.progressive.release()
        self.renderer.release()

    def with_render(self, **changes) -> None:
        """Change splatting settings (tau, k, opacity_norm, blend_linear, near)."""
        self.settings.render = replace(self.settings.render, **changes)
