"""The viewer's window: the model (model.py) in a glfw window, with its ImGui panel (panel.py),
mouse and keys (input.py) and the PNGs a script asks for (script.py).

One frame: take a finished load, apply mouse and keys, let the model bring the image up to date
(:meth:`ViewerModel.update`: sort, splat or refine), tonemap it into the left of the window, draw the
panel over the right, write the PNGs asked for.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from imgui_bundle import imgui

from dofview.camera import Camera
from dofview.framing import UpGuess
from dofview.scene import GaussianScene
from dofview.viewer.input import InputHandler
from dofview.viewer.model import ViewerModel
from dofview.viewer.panel import PANEL_WIDTH, draw_ui
from dofview.viewer.settings import ViewerSettings
from dofview.viewer.timing import FrameTimes
from dofview.viewer.window import Window


class Viewer:
    """A :class:`ViewerModel` (:attr:`model`) in a window. The panel, mouse and keys and the script
    act on the model through its public attributes and methods, and on the window's own fields here
    (help, fly mode, the panel's file fields, the script's capture queues)."""

    def __init__(self, window: Window, scene: GaussianScene, scene_path: Path, settings: ViewerSettings,
                 camera: Camera, cameras: list[Camera], up: UpGuess | None = None, raster: str = "auto",
                 **lod: object) -> None:
        self.window = window
        self.ctx = window.ctx
        self.show_help = False
        self.fly_mode = False
        self.times = FrameTimes()
        self.frames = 0
        self.save_path = "view.exr"
        self.save_png = True
        self.open_path = ""
        self.dialog = None  # a portable_file_dialogs.open_file while one is open
        self.capture_requests: list[Path] = []  # image area PNGs to write this frame (script)
        self.screenshot_requests: list[Path] = []  # whole-window PNGs to write this frame (script)
        # where the panel drew its parts, window units (panel.draw_ui; the tests check the layout)
        self.panel_layout: dict[str, float | list[float]] = {}
        self.handle_input = InputHandler()
        # lod: the streamed LOD set the scene is a level of, and its budget or level (ViewerModel's)
        self.model = ViewerModel(self.ctx, self._image_size, scene, scene_path, settings, camera, cameras, up, raster,
                                 **lod)
        self._titled: int | None = None  # the model's scene generation the title names
        self._title()

    def _image_size(self) -> tuple[int, int]:
        """(width, height) in framebuffer pixels of the image area left of the panel."""
        fw, fh = self.window.framebuffer_size
        panel = int(round(PANEL_WIDTH * self.window.pixel_ratio))
        return max(fw - panel, 1), max(fh, 1)

    def _title(self) -> None:
        if self._titled != self.model.generation:
            self.window.set_title(f"dofview — {self.model.scene_path.name}")
            self._titled = self.model.generation

    # ---- actions of the window -------------------------------------------------------------
    def save(self, path: str | Path | None = None, png: bool | None = None) -> None:
        """Save the view (:meth:`ViewerModel.save`) to ``path``, default the panel's file fields."""
        self.model.save(path or self.save_path, self.save_png if png is None else png)

    def copy_command(self) -> str:
        """Put the equivalent ``dofview render`` line on the clipboard."""
        command = self.model.command_line()
        self.window.set_clipboard(command)
        self.model.message = "copied the dofview render command to the clipboard"
        return command

    # ---- one frame -------------------------------------------------------------------------
    def _show(self, now: float) -> None:
        """Bring the image up to date and tonemap it into the image area."""
        m = self.model
        same_frame = m.update(now)
        self.ctx.screen.use()
        self.ctx.viewport = (0, 0, *self.window.framebuffer_size)
        self.ctx.clear(0.08, 0.08, 0.09)
        w, h = m.image_size
        fh = self.window.framebuffer_size[1]
        tm = m.settings.tonemap()
        m.renderer.tonemap_to(self.ctx.screen, (0, fh - h, w, h), tm, m.settings.focus_aid,
                              m.adapt(tm, now, same_frame), same_frame=same_frame)
        for path in self.capture_requests:
            self._write_screen(path, (0, fh - h, w, h))
        self.capture_requests.clear()

    def _write_screen(self, path: Path, viewport: tuple[int, int, int, int]) -> None:
        from dofview.io.png import write_png

        w, h = viewport[2], viewport[3]
        data = np.frombuffer(self.ctx.screen.read(viewport=viewport, components=3), np.uint8).reshape(h, w, 3)
        write_png(path, data[::-1])

    def frame(self) -> None:
        """Run one frame: events already polled by the caller."""
        now = time.perf_counter()
        self.times.begin(now)
        self.model.poll()
        self._title()
        self.window.begin_frame()
        self.handle_input(self)
        passes = self.model.passes
        self._show(now)
        if self.model.passes != passes:
            self.times.rendered(*self.model.last_pass)
        draw_ui(self)
        self.window.end_frame()
        fw, fh = self.window.framebuffer_size
        for path in self.screenshot_requests:
            self._write_screen(path, (0, 0, fw, fh))
        self.screenshot_requests.clear()
        self.window.swap()
        self.frames += 1

    def report(self) -> dict:
        """The model's state and the window's as plain data (the script's ``report`` action)."""
        return {
            **self.model.report(), "show_help": self.show_help, "fly_mode": self.fly_mode, "frames": self.frames,
            "times": {"frame_ms": self.times.frame_ms, "render_ms": self.times.render_ms,
                      "render": self.times.render_kind,
                      "status": self.times.status(self.model.renderer.stats.sort_ms),
                      "history_ms": [round(t, 1) for t in self.times.periods]},
            "clipboard": self.window.clipboard(),
            # ImGui's state after the last frame: a text field being edited takes the keys
            "keyboard_captured": imgui.get_io().want_capture_keyboard, "ui_active": imgui.is_any_item_active(),
            "panel": self.panel_layout,
        }

    def close(self) -> None:
        self.model.close()
