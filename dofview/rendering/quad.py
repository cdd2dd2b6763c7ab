"""The instanced-quad backend (the poster's method): the reference GPU path.

Per-Gaussian data lives in GPU storage buffers uploaded once per scene; only the draw order is
uploaded again, and only when the view changes (lens and exposure changes re-draw without
re-sorting). One instanced draw of four-vertex quads; see rendering/glsl/quads.vert for the math.

The order is sorted on the CPU (depth_order.py). For the viewer, :meth:`QuadBackend.request_order`
sorts off the UI thread (sort_thread.py) and the frames in between are drawn with the last order.
"""

from __future__ import annotations

import time

import moderngl
import numpy as np

from dofview.camera import Camera
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering.base import Renderer
from dofview.rendering.depth_order import front_to_back
from dofview.rendering.gl import load_shader
from dofview.rendering.sort_thread import SortThread
from dofview.rendering.uniforms import set_projection_uniforms
from dofview.scene import GaussianScene


class QuadBackend(Renderer):
    """The instanced-quad backend: one four-vertex quad per Gaussian, blended by the fixed-function
    blender in back-to-front order sorted on the CPU (see :class:`Renderer` for the arguments)."""

    name = "quad"

    def __init__(self, scene: GaussianScene, ctx: moderngl.Context | None = None, packed: bool = True) -> None:
        super().__init__(scene, ctx, packed)
        n = max(scene.count, 1)  # GL refuses zero-sized buffers; an empty scene draws 0 instances
        self._order = self.ctx.buffer(reserve=4 * n)
        self.program = self.ctx.program(vertex_shader=load_shader("quads.vert", self.shader_defines),
                                        fragment_shader=load_shader("quads.frag"))
        self._vao = self.ctx.vertex_array(self.program, [])
        self._host_order = np.zeros(0, np.uint32)  # back to front, as uploaded
        self._thread: SortThread | None = None  # started by the first request_order
        self._requested: bytes | None = None  # the view request_order was last asked for
        self._awaiting: bytes | None = None  # the view whose background order is not in yet

    @property
    def gpu_bytes(self) -> int:
        """Bytes of per-Gaussian GPU storage (scene buffers and the order buffer)."""
        return super().gpu_bytes + self._order.size

    # ---- depth order ---------------------------------------------------------------------------
    def sort(self, camera: Camera) -> None:
        """Sort on this thread and upload the back-to-front order for ``camera`` if its view differs
        from the last one sorted."""
        key = camera.view_key()
        if key == self._view_key:
            return
        t0 = time.perf_counter()
        order = front_to_back(self.scene.means, camera)[::-1]
        self.stats.sort_ms = (time.perf_counter() - t0) * 1e3
        self._upload_order(order, key)

    def _upload_order(self, back_to_front: np.ndarray, view_key: bytes) -> None:
        self._host_order = np.ascontiguousarray(back_to_front, dtype=np.uint32)
        if back_to_front.size:
            self._order.write(self._host_order.tobytes())
        self._view_key = view_key

    def front_to_back(self) -> np.ndarray:
        """(N,) uint32 the order in the order buffer, nearest first (kept on the CPU, no read-back)."""
        return self._host_order[::-1]

    def _order_for(self, camera: Camera) -> None:
        if camera.view_key() != self._awaiting:  # that view's order is being sorted in the background
            self.sort(camera)

    def request_order(self, camera: Camera) -> bool:
        """Take in a finished background sort, and send ``camera``'s view to the sort thread when it
        is not the view asked for last (the first request sorts here: there is no order to draw
        with yet). Draws of the requested view meanwhile use the last order; draws of other views
        (lens-shifted passes, other cameras) sort here as before."""
        key = camera.view_key()
        if self._requested is None:
            self.sort(camera)
            self._requested = key
            return False
        arrived = self._take_order()
        if key != self._requested:
            if self._thread is None:
                self._thread = SortThread()
            self._thread.request(self.scene.means, camera)
            self.stats.sort_requests += 1
            self._requested = self._awaiting = key
        return arrived

    def _take_order(self) -> bool:
        res = self._thread.result() if self._thread is not None else None
        if res is None:
            return False
        self._upload_order(res.order, res.view_key)
        self.stats.sort_ms = res.ms
        if res.view_key == self._awaiting:
            self._awaiting = None
        return True

    @property
    def sort_pending(self) -> bool:
        return self._awaiting is not None or (self._thread is not None and self._thread.pending)

    def _scene_swapped(self, order: tuple[Camera, np.ndarray] | None) -> None:
        """An order buffer for the new count; the sort thread (which may be sorting the old means)
        is let go and the next background sort starts a new one; ``order`` becomes the order in use,
        and the view asked for, so the views that follow are sorted in the background."""
        if self._order.size < 4 * max(self.scene.count, 1):
            self._order.release()
            self._order = self.ctx.buffer(reserve=4 * max(self.scene.count, 1))
        if self._thread is not None:
            self._thread.close(wait=False)
            self._thread = None
        self._host_order = np.zeros(0, np.uint32)
        self._requested = self._awaiting = None
        if order is not None:
            camera, ftb = order
            self._upload_order(ftb[::-1], camera.view_key())
            self._requested = self._view_key

    # ---- drawing -------------------------------------------------------------------------------
    def _prepare(self, camera: Camera, lens: Lens, settings: RenderSettings, count: bool) -> None:
        p = self.program
        set_projection_uniforms(p, camera, lens, settings)
        p["u_count"].value = count

    def _splat_range(self, first: int, end: int, target: moderngl.Framebuffer,
                     box: tuple[int, int, int, int] | None = None) -> None:
        self._bind_scene()
        self._order.bind_to_storage_buffer(3)
        self._counter.bind_to_storage_buffer(4)
        target.use()
        self.ctx.viewport = (0, 0, *target.size)
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
        self.ctx.blend_equation = moderngl.FUNC_ADD
        if box is not None:  # a depth slice's window: what lies beyond stays as it was
            x0, y0, x1, y1 = box
            self.ctx.scissor = (x0, target.height - y1, max(x1 - x0, 0), max(y1 - y0, 0))
        if end > first:
            self.program["u_first"].value = self.scene.count - end  # the order buffer runs back to front
            self._vao.render(moderngl.TRIANGLE_STRIP, vertices=4, instances=end - first)
        self.ctx.disable(moderngl.BLEND)
        self.ctx.scissor = None

    def _release_backend(self) -> None:
        if self._thread is not None:
            self._thread.close()
        for obj in (self._order, self._vao, self.program):
            obj.release()
