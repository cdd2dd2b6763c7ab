"""The desktop window: glfw with an OpenGL 4.3 core context, moderngl on it, Dear ImGui on top.

imgui_bundle ships its own libglfw and its C++ glfw/OpenGL3 backends; importing imgui_bundle
before ``glfw`` points the Python glfw binding at that same library, so both share one glfw state.
"""

from __future__ import annotations

import ctypes
import os
import sys
from typing import Callable

import glfw
import moderngl
from imgui_bundle import imgui  # noqa: I001  (must come before glfw, see module docstring)

from dofview.errors import DofviewError
from dofview.rendering.gl import GL_REQUIRED

HEADLESS_HINT = "use dofview render for headless images"


def _glfw_error() -> str:
    code, text = glfw.get_error()
    return (text.decode() if isinstance(text, bytes) else str(text or "")) or f"glfw error {code}"


def check_display() -> None:
    """Refuse early, with one line, where no window system can be reached."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise DofviewError(f"no display (DISPLAY and WAYLAND_DISPLAY are not set); {HEADLESS_HINT}")


class Window:
    """A glfw window with a current GL 4.3 core context, a moderngl context and an ImGui frame loop.

    Sizes: ``window_size`` is in screen coordinates (mouse positions, ImGui layout);
    ``framebuffer_size`` in pixels (GL). They differ on HiDPI screens.
    """

    def __init__(self, title: str, width: int, height: int, on_drop: Callable[[list[str]], None] | None = None) -> None:
        check_display()
        glfw.ERROR_REPORTING = False  # errors are read with glfw.get_error and reported as DofviewError
        if not glfw.init():
            raise DofviewError(f"no display ({_glfw_error()}); {HEADLESS_HINT}")
        major, minor = GL_REQUIRED // 100, GL_REQUIRED % 100 // 10
        glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, major)
        glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, minor)
        glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
        glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
        glfw.window_hint(glfw.SCALE_TO_MONITOR, True)
        self.handle = glfw.create_window(width, height, title, None, None)
        if not self.handle:
            err = _glfw_error()
            glfw.terminate()
            raise DofviewError(f"cannot open a window with OpenGL {major}.{minor} core ({err}); {HEADLESS_HINT}")
        glfw.make_context_current(self.handle)
        glfw.swap_interval(1)
        self.ctx = moderngl.create_context(require=GL_REQUIRED)
        if on_drop:
            glfw.set_drop_callback(self.handle, lambda _win, paths: on_drop(list(paths)))
        imgui.create_context()
        imgui.get_io().set_ini_filename("")  # no imgui.ini next to the user's files
        # ImGui's glfw backend chains to callbacks installed before it (the drop callback above)
        address = ctypes.cast(self.handle, ctypes.c_void_p).value
        imgui.backends.glfw_init_for_opengl(address, True)
        imgui.backends.opengl3_init(f"#version {GL_REQUIRED}")

    @property
    def window_size(self) -> tuple[int, int]:
        return glfw.get_window_size(self.handle)

    @property
    def framebuffer_size(self) -> tuple[int, int]:
        return glfw.get_framebuffer_size(self.handle)

    @property
    def pixel_ratio(self) -> float:
        """Framebuffer pixels per window unit (1 on ordinary screens, 2 on most HiDPI ones)."""
        w, _ = self.window_size
        return self.framebuffer_size[0] / max(w, 1)

    @property
    def should_close(self) -> bool:
        return bool(glfw.window_should_close(self.handle))

    def close(self) -> None:
        glfw.set_window_should_close(self.handle, True)

    def poll(self, timeout: float | None = None) -> None:
        """Process window events; wait up to ``timeout`` seconds for one when given (idle)."""
        if timeout:
            glfw.wait_events_timeout(timeout)
        else:
            glfw.poll_events()

    def begin_frame(self) -> None:
        imgui.backends.opengl3_new_frame()
        imgui.backends.glfw_new_frame()
        imgui.new_frame()

    def end_frame(self) -> None:
        """Draw the ImGui layer over the default framebuffer (not yet shown: see :meth:`swap`)."""
        imgui.render()
        self.ctx.screen.use()
        w, h = self.framebuffer_size
        self.ctx.viewport = (0, 0, w, h)
        imgui.backends.opengl3_render_draw_data(imgui.get_draw_data())

    def swap(self) -> None:
        glfw.swap_buffers(self.handle)

    def set_clipboard(self, text: str) -> None:
        glfw.set_clipboard_string(self.handle, text)

    def clipboard(self) -> str:
        text = glfw.get_clipboard_string(self.handle)
        return text.decode() if isinstance(text, bytes) else (text or "")

    def set_title(self, title: str) -> None:
        glfw.set_window_title(self.handle, title)

    def destroy(self) -> None:
        imgui.backends.opengl3_shutdown()
        imgui.backends.glfw_shutdown()
        imgui.destroy_context()
        glfw.destroy_window(self.handle)
        glfw.terminate()
