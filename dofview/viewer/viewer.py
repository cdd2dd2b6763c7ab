"""The viewer's state and frame loop: scene, renderer, camera controls, lens/image settings.

One frame: take a finished load or sort, apply mouse and keys, advance a focus pull, request a
sort when the view moved (drawn meanwhile with the last order), splat again only when the camera,
lens or splatting settings changed, tonemap the image into the left of the window, draw the
panel over the right. Exposure, gamma, background and the focus aid only re-run the tonemap.
"""

from __future__ import annotations

import json
import math
import time
from collections import deque
from dataclasses import replace
from pathlib import Path

import moderngl
import numpy as np
from imgui_bundle import imgui

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
from dofview.rendering.progressive import ProgressiveLens
from dofview.rendering.sorter import SortThread
from dofview.scene import GaussianScene
from dofview.tonemap.stats import Stats, StatsSmoother, cdf_domain
from dofview.viewer.controls import ViewControls
from dofview.viewer.input import InputHandler
from dofview.viewer.loader import SceneLoad
from dofview.viewer.panel import PANEL_WIDTH, draw_ui
from dofview.viewer.settings import START_COC_PX, FocusPull, ViewerSettings
from dofview.viewer.window import Window

COUNT_EVERY_S = 0.5  # how often the drawn-Gaussian counter is read back (it costs a GPU sync)
FRAME_HISTORY = 120


class Viewer:
    """Everything the window shows. The panel (panel.py) and the script (script.py) drive it
    through its attributes and methods, the same ones mouse and keys use."""

    def __init__(self, window: Window, scene: GaussianScene, scene_path: Path, settings: ViewerSettings,
                 camera: Camera, cameras: list[Camera], up: UpGuess | None = None, raster: str = "auto") -> None:
        self.window = window
        self.ctx = window.ctx
        self.settings = settings
        self.cameras = cameras
        self.raster = raster  # renderer backend name (dofview.rendering.BACKENDS, or "auto")
        self.view_index: int | None = None
        self.sorter = SortThread()
        self.pull = FocusPull()
        self.smoother = StatsSmoother()  # adaptive tone mapping: statistics smoothed in time
        self._frame_stats: Stats | None = None
        self._stats_time: float | None = None
        self.loading: SceneLoad | None = None
        self.message = ""  # last status line (saved file, copied command)
        self.error = ""  # last error (failed load or save), shown in red until the next action
        self.show_help = False
        self.fly_mode = False
        self.fly_speed = 1.0  # scene units per second
        self.frame_ms: deque[float] = deque(maxlen=FRAME_HISTORY)
        self.render_ms = 0.0
        self.frames = 0
        self.sort_requests = 0  # views sent to the sort thread
        self.splat_draws = 0  # splatting passes shown (exposure, gamma, background, focus aid add none)
        self.save_path = "view.exr"
        self.save_png = True
        self.open_path = ""
        self.dialog = None  # a portable_file_dialogs.open_file while one is open
        self.capture_requests: list[Path] = []  # image area PNGs to write this frame (script)
        self.screenshot_requests: list[Path] = []  # whole-window PNGs to write this frame (script)
        self.handle_input = InputHandler()
        self._last_frame = time.perf_counter()
        self._last_count = -math.inf
        self._drawn_key: tuple | None = None
        self._sort_key: bytes | None = None  # the view the newest sort was asked for
        self._order_key: bytes | None = None  # the view the uploaded order belongs to
        self.generation = 0
        self.depth_span = (1.0, 1.0)  # near and far depth in view (2nd/98th percentile), scene units
        # the overview camera (R, U, a scene opened without cameras) frames the scene for this
        # width, height (pixels) and horizontal field of view (degrees); app.py sets the window's
        self.framing = (800, 600, 50.0)
        # the lens a view starts with (R, U, N re-derive it): the --focus / --aperture given for the
        # scene opened first, None for the first-frame rule (see frame_lens)
        self.start_focus: float | None = None
        self.start_aperture: float | None = None
        self.start_blur: BlurSpec | None = None  # --blur: resolved again on each view's own depths
        # where the panel drew its parts, window units (panel.draw_ui; the tests check the layout)
        self.panel_layout: dict[str, float | list[float]] = {}
        self.renderer: Renderer | None = None
        self.set_scene(scene, scene_path, camera, up)

    # ---- scene and views -------------------------------------------------------------------
    def set_scene(self, scene: GaussianScene, path: Path, camera: Camera | None = None, up: UpGuess | None = None) -> None:
        """Show ``scene``: upload it, start at ``camera`` (default: view 0 of :attr:`cameras`, else a
        camera framing the scene from the ``up`` given or guessed) and sort once up front.

        The new scene is uploaded before the old one is released, so a failed upload keeps it.
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
        self._drawn_key = self._sort_key = None
        self._last_count = -math.inf  # count the new scene's first frame
        self.window.set_title(f"dofview — {self.scene_path.name}")

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
        """(width, height) in framebuffer pixels of the image area left of the panel."""
        fw, fh = self.window.framebuffer_size
        panel = int(round(PANEL_WIDTH * self.window.pixel_ratio))
        return max(fw - panel, 1), max(fh, 1)

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
        """Draw and read back a pinhole pass of the current view (sorted first if ``sort``), and
        take the depth range in view from it (:attr:`depth_span`, which scales the sliders)."""
        self.renderer.draw(self.camera(), Lens(1.0, 0.0), self.settings.render, sort=sort)
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

    def save(self, path: str | Path | None = None, png: bool | None = None) -> None:
        """Write the current view as EXR (and PNG beside it), exactly as ``dofview render`` would."""
        out = Path(path or self.save_path).expanduser()
        png = self.save_png if png is None else png
        self.error = ""
        try:
            if out.suffix.lower() != ".exr":
                raise DofviewError(f"{out}: output must be an .exr file")
            camera = self.camera()
            save_render(self.renderer, camera, self.lens(camera), self.settings.tonemap(), self.settings.render,
                        str(self.scene_path), out, out.with_suffix(".png") if png else None,
                        lens_info=self.settings.lens_info(),
                        stats=self.smoother.state if self.settings.tonemap().operator.adaptive else None)
        except DofviewError as e:
            self.error = str(e)
            return
        finally:
            self._drawn_key = None
        self.message = f"saved {out}" + (" and .png" if png else "")

    def copy_command(self) -> str:
        """Put the equivalent ``dofview render`` line on the clipboard."""
        command = self.command_line()
        self.window.set_clipboard(command)
        self.message = "copied the dofview render command to the clipboard"
        return command

    # ---- one frame -------------------------------------------------------------------------
    def _take_results(self) -> None:
        if self.loading is not None and self.loading.done:
            self._finish_load()
        res = self.sorter.result()
        if res is not None and res.generation == self.generation:
            self.renderer.set_order(res.order, res.view_key)
            self._order_key = res.view_key
            self.renderer.stats.sort_ms = res.ms
            self._drawn_key = None

    def _state_key(self, camera: Camera, lens: Lens) -> tuple:
        return (camera.view_key(), camera.width, camera.height, camera.fx, lens, self.settings.render,
                self.settings.colour_space)

    def _render(self, now: float) -> None:
        """Splat if anything the splats depend on changed, then tonemap into the image area."""
        if self.pull.active:
            self.settings.focus = self.pull.value(now)
        camera = self.camera()
        lens = self.lens(camera)
        key = camera.view_key()
        requested = False  # a new order is on its way from the sort thread
        if self._sort_key is None or self.renderer.gpu_sort:  # a new scene, or a backend that sorts on the GPU
            self.renderer.sort(camera)  # (a no-op when the view did not move)
            self._sort_key = self._order_key = key
        elif key != self._sort_key:
            self.sorter.request(self.scene.means, camera, self.generation)
            self.sort_requests += 1
            self._sort_key = key
            requested = True
        state = self._state_key(camera, lens)
        drawn = state == self._drawn_key  # the targets already hold this frame
        if not drawn:
            if self.progressive.samples and not requested:  # its passes left a lens-shifted camera's order
                self.renderer.sort(camera)
            self.renderer.encoded_scene = self.settings.colour_space == "srgb"
            self.scene.colour_space = self.settings.colour_space
            count = now - self._last_count >= COUNT_EVERY_S
            t0 = time.perf_counter()
            self.renderer.draw(camera, lens, self.settings.render, count=count, sort=False)
            self.ctx.finish()
            self.splat_draws += 1
            self.render_ms = (time.perf_counter() - t0) * 1e3
            if count:
                self._last_count = now
            self._drawn_key = state
            # the single-pass image is kept only where refinement can follow (it copies two float targets)
            self.progressive.restart(keep_single=lens.aperture > 0 and self.settings.lens_samples_max > 0)
        elif (lens.aperture > 0 and self.progressive.samples < self.settings.lens_samples_max and not self.busy
              and self._order_key == self._sort_key):
            self.progressive.add(camera, lens, self.settings.render)  # still: one more pinhole pass
            self.progressive.show()
            drawn = False  # the targets now hold the refined image
        self.ctx.screen.use()
        self.ctx.viewport = (0, 0, *self.window.framebuffer_size)
        self.ctx.clear(0.08, 0.08, 0.09)
        w, h = camera.width, camera.height
        fh = self.window.framebuffer_size[1]
        tm = self.settings.tonemap()
        self.renderer.tonemap_to(self.ctx.screen, (0, fh - h, w, h), tm, self.settings.focus_aid, self._adapt(tm, now, drawn),
                                 same_frame=drawn)
        for path in self.capture_requests:
            self._write_screen(path, (0, fh - h, w, h))
        self.capture_requests.clear()

    def _write_screen(self, path: Path, viewport: tuple[int, int, int, int]) -> None:
        from dofview.io.png import write_png

        w, h = viewport[2], viewport[3]
        data = np.frombuffer(self.ctx.screen.read(viewport=viewport, components=3), np.uint8).reshape(h, w, 3)
        write_png(path, data[::-1])

    def _adapt(self, tm, now: float, same_frame: bool = False) -> Stats | None:
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
        """Work in flight that will change the image: a load, a sort or a focus pull."""
        return self.loading is not None or self.sorter.pending or self.pull.active or self.adapting

    @property
    def settled(self) -> bool:
        """The image shows the current state with the order sorted for the current view."""
        return not self.busy and self._order_key == self._sort_key and self._drawn_key is not None

    def frame(self) -> None:
        """Run one frame: events already polled by the caller."""
        now = time.perf_counter()
        self.frame_ms.append((now - self._last_frame) * 1e3)
        self._last_frame = now
        self._take_results()
        self.window.begin_frame()
        self.handle_input(self)
        self._render(now)
        draw_ui(self)
        self.window.end_frame()
        fw, fh = self.window.framebuffer_size
        for path in self.screenshot_requests:
            self._write_screen(path, (0, 0, fw, fh))
        self.screenshot_requests.clear()
        self.window.swap()
        self.frames += 1

    def report(self) -> dict:
        """The state as plain data (the script's ``report`` action writes it as JSON)."""
        camera = self.camera()
        lens = self.lens(camera)
        tm = self.settings.tonemap()
        rs = self.settings.render
        return {
            "scene": str(self.scene_path), "count": self.scene.count, "generation": self.generation,
            "camera": {"width": camera.width, "height": camera.height, "fx": camera.fx, "fy": camera.fy,
                       "cx": camera.cx, "cy": camera.cy, "R": camera.R.tolist(), "T": camera.T.tolist(),
                       "name": camera.name},
            "lens": {"focus": lens.focus, "aperture": lens.aperture},
            "tonemap": {"exposure": tm.exposure, "gamma": tm.gamma, "background": list(tm.background),
                        "operator": tm.operator.name, "params": tm.operator.params(),
                        "stats": json.loads(self.smoother.state.to_json()) if self.smoother.state is not None
                        and tm.operator.adaptive else None, "locked": self.settings.stats_lock},
            "render": {"tau": rs.tau, "k": rs.k, "opacity_norm": rs.opacity_norm, "blend_linear": rs.blend_linear,
                       "near": rs.near, "cut": rs.cut},
            "colour_space": self.settings.colour_space, "focus_aid": self.settings.focus_aid,
            "focus_pull_target": self.pull.target, "pivot": self.controls.pivot.tolist(),
            "show_help": self.show_help, "fly_mode": self.fly_mode, "up": self.up.tolist(), "up_label": self.up_label,
            "depth_span": list(self.depth_span), "view_index": self.view_index, "views": len(self.cameras),
            "drawn": self.renderer.stats.drawn, "total": self.renderer.stats.total,
            "sort_ms": self.renderer.stats.sort_ms, "frames": self.frames,
            "message": self.message, "error": self.error, "command": self.command_line(),
            "clipboard": self.window.clipboard(), "sort_requests": self.sort_requests,
            "splat_draws": self.splat_draws, "lens_samples": self.progressive.samples,
            # ImGui's state after the last frame: a text field being edited takes the keys
            "keyboard_captured": imgui.get_io().want_capture_keyboard, "ui_active": imgui.is_any_item_active(),
            "panel": self.panel_layout,
        }

    def close(self) -> None:
        self.sorter.close()
        self.progressive.release()
        self.renderer.release()

    def with_render(self, **changes) -> None:
        """Change splatting settings (tau, k, opacity_norm, blend_linear, near)."""
        self.settings.render = replace(self.settings.render, **changes)
