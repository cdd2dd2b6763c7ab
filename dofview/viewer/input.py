"""Mouse and keys on the image: camera moves, click-to-focus and the shortcuts (see HELP).

Read through ImGui's input state, so anything ImGui is using (the panel, a text field) is left
alone. Mouse positions are in window units; the image is in framebuffer pixels (×pixel_ratio).
"""

from __future__ import annotations

from typing import Protocol

from imgui_bundle import imgui

from dofview.camera import Camera
from dofview.viewer.controls import ViewControls
from dofview.viewer.settings import ViewerSettings

CLICK_SLOP_PX = 3.0  # a press that moves less than this (window units) is a click, not a drag
FLY_FAST = 4.0  # speed factor with Shift held
FLY_SPEED_STEP = 1.25  # fly speed factor per scroll step

HELP: tuple[tuple[str, str], ...] = (
    ("Left click", "focus on what is under the cursor"),
    ("Left drag", "orbit around the pivot (fly mode: look around)"),
    ("Right/middle drag, Shift+drag", "pan"),
    ("Scroll", "zoom towards the pivot (fly mode: fly speed)"),
    ("Tab", "switch between orbit and fly mode"),
    ("W A S D, Q E (fly mode)", "forward, left, back, right, down, up (Shift: faster)"),
    ("F", "focus on what is under the cursor"),
    ("G", "focus aid: tint the sharp band"),
    ("R", "reset to the camera that frames the scene (with the starting focus and aperture)"),
    ("U", "next world up (-y, +z, +y, -z, +x, -x): frame the scene from it (starting focus, aperture)"),
    ("N / P, Page Down / Page Up", "next / previous view of cameras.json (starting focus, aperture)"),
    ("Ctrl+S", "save the view (EXR + PNG)"),
    ("Ctrl+C", "copy the equivalent dofview render command"),
    ("F1 or H", "this help"),
    ("Drop a file or folder", "scene or run folder: open it; .json: use its cameras"),
)


class _Window(Protocol):
    pixel_ratio: float


class ModelActions(Protocol):
    """What input may read and do in the viewer model (viewer/model.py's ViewerModel)."""

    controls: ViewControls
    settings: ViewerSettings
    fly_speed: float

    @property
    def image_size(self) -> tuple[int, int]: ...
    def camera(self) -> Camera: ...
    def focus_at(self, x: float, y: float) -> None: ...
    def reset_view(self) -> None: ...
    def cycle_up(self) -> None: ...
    def step_view(self, step: int) -> None: ...


class ViewerActions(Protocol):
    """What the input handler may read and do: the window's fields and actions, and its model's;
    the viewer implements it, input never imports the viewer."""

    window: _Window
    model: ModelActions
    fly_mode: bool
    show_help: bool

    def save(self) -> None: ...
    def copy_command(self) -> None: ...


def _over_image(viewer: ViewerActions, x: float, y: float) -> bool:
    w, h = viewer.model.image_size
    r = viewer.window.pixel_ratio
    return 0 <= x * r < w and 0 <= y * r < h


def _fly_keys(viewer: ViewerActions, dt: float) -> None:
    def axis(plus, minus) -> float:
        return float(imgui.is_key_down(plus)) - float(imgui.is_key_down(minus))

    right, down, forward = axis(imgui.Key.d, imgui.Key.a), axis(imgui.Key.q, imgui.Key.e), axis(imgui.Key.w, imgui.Key.s)
    fast = FLY_FAST if imgui.get_io().key_shift else 1.0
    viewer.model.controls.fly(right, down, forward, viewer.model.fly_speed * fast * dt)


class InputHandler:
    """Turns this frame's mouse and keys into viewer actions; remembers a press across frames."""

    def __init__(self) -> None:
        self.press: tuple[float, float] | None = None  # where a button went down on the image
        self.dragging = False

    def __call__(self, viewer: ViewerActions) -> None:
        io = imgui.get_io()
        x, y = io.mouse_pos.x, io.mouse_pos.y
        if self.press is not None or (not io.want_capture_mouse and _over_image(viewer, x, y)):
            self._mouse(viewer, io, x, y)
        if not io.want_capture_keyboard:
            _keys(viewer, io, x, y)

    def _mouse(self, viewer: ViewerActions, io, x: float, y: float) -> None:
        r = viewer.window.pixel_ratio
        if self.press is None and any(imgui.is_mouse_clicked(b) for b in range(3)):
            self.press, self.dragging = (x, y), False
        if io.mouse_wheel and self.press is None:
            if viewer.fly_mode:
                viewer.model.fly_speed *= FLY_SPEED_STEP ** io.mouse_wheel
            else:
                viewer.model.controls.zoom(io.mouse_wheel)
        if self.press is None:
            return
        px, py = self.press
        left, pan_button = imgui.is_mouse_down(0), imgui.is_mouse_down(1) or imgui.is_mouse_down(2)
        if not self.dragging and (x - px) ** 2 + (y - py) ** 2 > CLICK_SLOP_PX ** 2:
            self.dragging = True
        dx, dy = io.mouse_delta.x, io.mouse_delta.y
        if self.dragging and (dx or dy):
            if pan_button or (left and io.key_shift):
                viewer.model.controls.pan(dx * r, dy * r, viewer.model.camera().fx)
            elif left and viewer.fly_mode:
                viewer.model.controls.look(dx, dy)
            elif left:
                viewer.model.controls.orbit(dx, dy)
        if imgui.is_mouse_released(0) and not self.dragging:
            viewer.model.focus_at(px * r, py * r)
        if not (left or pan_button):
            self.press = None


def _keys(viewer: ViewerActions, io, x: float, y: float) -> None:
    r = viewer.window.pixel_ratio
    if viewer.fly_mode:
        _fly_keys(viewer, min(io.delta_time, 0.1))
    pressed = imgui.is_key_pressed
    if pressed(imgui.Key.f1, False) or pressed(imgui.Key.h, False):
        viewer.show_help = not viewer.show_help
    if pressed(imgui.Key.escape, False):
        viewer.show_help = False
    if pressed(imgui.Key.tab, False):
        viewer.fly_mode = not viewer.fly_mode
    if pressed(imgui.Key.f, False) and _over_image(viewer, x, y):
        viewer.model.focus_at(x * r, y * r)
    if pressed(imgui.Key.g, False):
        viewer.model.settings.focus_aid = not viewer.model.settings.focus_aid
    if pressed(imgui.Key.r, False):
        viewer.model.reset_view()
    if pressed(imgui.Key.u, False):
        viewer.model.cycle_up()
    if pressed(imgui.Key.n, False) or pressed(imgui.Key.page_down, False):
        viewer.model.step_view(1)
    if pressed(imgui.Key.p, False) or pressed(imgui.Key.page_up, False):
        viewer.model.step_view(-1)
    if io.key_ctrl and pressed(imgui.Key.s, False):
        viewer.save()
    if io.key_ctrl and pressed(imgui.Key.c, False):
        viewer.copy_command()
