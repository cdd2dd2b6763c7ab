"""Scripted mode (``dofview view … --script actions.json``): drive the real window from a file.

The file holds a JSON list of actions, run one per frame through the same viewer methods that
mouse, keys and panel use, then the window closes. Actions (pixels are image pixels, top-left
origin, framebuffer units; paths are relative to the working directory):

    {"do": "set", "focus": 2.0, "aperture": 40, "ev": 1, "focus_aid": true, "tau": 0.0, ...}
        any lens/image setting (see ViewerSettings) or splatting setting (tau, k, opacity_norm,
        blend_linear, near); "focus" jumps unless "smooth": true
    {"do": "click", "x": 120, "y": 200}        click-to-focus, as a left click there
    {"do": "orbit" | "pan" | "look", "dx": 30, "dy": 0}   a mouse drag of that many pixels
    {"do": "zoom", "steps": 1}                  scroll
    {"do": "view", "name": "view_003"} / {"do": "view", "index": 3} / {"do": "next"} / {"do": "reset"}
    {"do": "open", "path": "other.ply"}         load (waits until done or failed)
    {"do": "save", "path": "out.exr", "png": true}
    {"do": "copy_command"}
    {"do": "help", "show": true}
    {"do": "frames", "n": 5}                    run n frames
    {"do": "wait", "seconds": 0.3}              run frames for that long
    {"do": "settle"}                            run frames until no load, sort or focus pull is pending
    {"do": "still", "samples": 16}              run frames until the thin lens has that many samples
                                                (set "lens_samples_max" to the same to stop there)
    {"do": "capture", "path": "image.png"}      the image area as shown, before the panel is drawn
    {"do": "screenshot", "path": "window.png"}  the whole window, panel included
    {"do": "report", "path": "state.json"}      the viewer's state (camera, lens, tonemap, error…)
    {"do": "quit"}

Raw input goes through ImGui's input queue, the path glfw's callbacks feed, so mouse handling
and shortcuts are exercised as a user would (positions in window units):

    {"do": "mouse_move", "x": 100, "y": 80}
    {"do": "mouse_button", "button": 0, "down": true}    0 left, 1 right, 2 middle
    {"do": "scroll", "steps": 1}
    {"do": "key", "key": "f1", "down": true}             an ImGui key name (imgui.Key.<name>)

capture, screenshot and report settle first, unless given "settle": false.
"""

from __future__ import annotations

import json
import time
from dataclasses import fields
from pathlib import Path
from typing import TYPE_CHECKING

from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.io.jsonfile import read_json
from dofview.viewer.settings import ViewerSettings

if TYPE_CHECKING:
    from dofview.viewer.viewer import Viewer

SETTLE_TIMEOUT_S = 120.0
_SETTINGS = {f.name for f in fields(ViewerSettings)} - {"render"}
_RENDER = {f.name for f in fields(RenderSettings)}
_ACTIONS = {"set", "click", "orbit", "pan", "look", "zoom", "view", "next", "reset", "open", "save",
            "copy_command", "help", "frames", "wait", "settle", "still", "capture", "screenshot", "report", "quit",
            "mouse_move", "mouse_button", "scroll", "key"}


def load_script(path: str | Path) -> list[dict]:
    """Read and check a script file: a JSON list of objects with a known "do"."""
    path = Path(path)
    actions = read_json(path, "script")
    if not isinstance(actions, list):
        raise DofviewError(f"{path}: a script is a JSON list of actions")
    for i, a in enumerate(actions):
        if not isinstance(a, dict) or a.get("do") not in _ACTIONS:
            raise DofviewError(f"{path}: action {i} must be an object whose \"do\" is one of {', '.join(sorted(_ACTIONS))}")
        if a["do"] == "set":
            unknown = set(a) - _SETTINGS - _RENDER - {"do", "smooth"}
            if unknown:
                raise DofviewError(f"{path}: action {i}: unknown setting(s) {', '.join(sorted(unknown))}")
    return actions


class ScriptRunner:
    """Runs a script's actions against a viewer, at most one action per frame."""

    def __init__(self, actions: list[dict], source: str = "script") -> None:
        self.actions = list(actions)
        self.source = source
        self.index = 0
        self._until: float | None = None  # end time of a "wait"
        self._frames_left: int | None = None
        self._settle_since: float | None = None
        self._opening = False

    @property
    def finished(self) -> bool:
        return self.index >= len(self.actions)

    def step(self, viewer: "Viewer") -> None:
        """Advance before a frame: run the next action, or keep waiting for the current one."""
        if self.finished:
            viewer.window.close()
            return
        action = self.actions[self.index]
        try:
            done = self._run(viewer, action)
        except (KeyError, TypeError, ValueError) as e:
            raise DofviewError(f"{self.source}: action {self.index} {json.dumps(action)}: {e!r}") from None
        if done:
            self.index += 1

    def _settled(self, viewer: "Viewer") -> bool:
        now = time.perf_counter()
        if self._settle_since is None:
            self._settle_since = now
        if viewer.model.settled:
            self._settle_since = None
            return True
        if now - self._settle_since > SETTLE_TIMEOUT_S:
            raise DofviewError(f"{self.source}: action {self.index}: the viewer did not settle in {SETTLE_TIMEOUT_S:g} s")
        return False

    def _run(self, v: "Viewer", a: dict) -> bool:  # noqa: C901 - one branch per action keeps it readable
        do = a["do"]
        if do == "set":
            render = {k: a[k] for k in a if k in _RENDER}
            if render:
                v.model.with_render(**render)
            for k in a:
                if k in _SETTINGS and k != "focus":
                    value = a[k]
                    setattr(v.model.settings, k, tuple(value) if isinstance(value, list) else value)
            if "focus" in a:
                v.model.set_focus(float(a["focus"]), smooth=bool(a.get("smooth", False)))
        elif do == "click":
            v.model.focus_at(float(a["x"]), float(a["y"]))
        elif do in ("orbit", "look"):
            getattr(v.model.controls, do)(float(a["dx"]), float(a["dy"]))
        elif do == "pan":
            v.model.controls.pan(float(a["dx"]), float(a["dy"]), v.model.camera().fx)
        elif do == "zoom":
            v.model.controls.zoom(float(a["steps"]))
        elif do == "view":
            names = [c.name for c in v.model.cameras]
            v.model.set_view(names.index(a["name"]) if "name" in a else int(a["index"]))
        elif do == "next":
            v.model.step_view(1)
        elif do == "reset":
            v.model.reset_view()
        elif do == "open":
            if not self._opening:
                v.model.open_file(a["path"])
                self._opening = True
            if v.model.loading is not None:
                return False
            self._opening = False
        elif do == "save":
            v.save(a["path"], bool(a.get("png", False)))
        elif do == "copy_command":
            v.copy_command()
        elif do == "help":
            v.show_help = bool(a.get("show", True))
        elif do == "frames":
            if self._frames_left is None:
                self._frames_left = int(a["n"])
            self._frames_left -= 1
            if self._frames_left > 0:
                return False
            self._frames_left = None
        elif do == "wait":
            if self._until is None:
                self._until = time.perf_counter() + float(a["seconds"])
            if time.perf_counter() < self._until:
                return False
            self._until = None
        elif do == "settle":
            return self._settled(v)
        elif do == "still":
            if v.model.progressive.samples >= int(a["samples"]):
                self._settle_since = None
                return True
            now = time.perf_counter()
            self._settle_since = self._settle_since or now
            if now - self._settle_since > SETTLE_TIMEOUT_S:
                raise DofviewError(f"{self.source}: action {self.index}: the thin lens did not reach "
                                   f"{a['samples']} samples in {SETTLE_TIMEOUT_S:g} s (aperture 0, or lens_samples_max lower?)")
            return False
        elif do in ("capture", "screenshot", "report"):
            if a.get("settle", True) and not self._settled(v):
                return False
            path = Path(a["path"])
            if do == "capture":
                v.capture_requests.append(path)
            elif do == "screenshot":
                v.screenshot_requests.append(path)
            else:
                path.write_text(json.dumps(v.report(), indent=1))
        elif do in ("mouse_move", "mouse_button", "scroll", "key"):
            _feed_input(a)
        elif do == "quit":
            self.index = len(self.actions)
            v.window.close()
        return True


def _feed_input(a: dict) -> None:
    from imgui_bundle import imgui

    io = imgui.get_io()
    do = a["do"]
    if do == "mouse_move":
        io.add_mouse_pos_event(float(a["x"]), float(a["y"]))
    elif do == "mouse_button":
        io.add_mouse_button_event(int(a["button"]), bool(a["down"]))
    elif do == "scroll":
        io.add_mouse_wheel_event(0.0, float(a["steps"]))
    else:
        io.add_key_event(getattr(imgui.Key, a["key"]), bool(a.get("down", True)))
