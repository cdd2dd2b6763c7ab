"""The instanced-quad backend (the poster's method): the reference GPU path.

Per-Gaussian data lives in GPU storage buffers uploaded once per scene; only the draw order is
uploaded again, and only when the view changes (lens and exposure changes re-draw without
re-sorting). One instanced draw of four-vertex quads; see rendering/glsl/quads.vert for the math.
"""

from __future__ import annotations

import time

import moderngl
import numpy as np

from dofview.camera import Camera
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering.base import Renderer
from dofview.rendering.gl import load_shader
from dofview.rendering.sort import front_to_back
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
        self._counter = self.ctx.buffer(reserve=4)
        self.program = self.ctx.program(vertex_shader=load_shader("quads.vert", self.shader_defines),
                                        fragment_shader=load_shader("quads.frag"))
        self._vao = self.ctx.vertex_array(self.program, [])
        self._view_key: bytes | None = None

    @property
    def gpu_bytes(self) -> int:
        """Bytes of per-Gaussian GPU storage (scene buffers and the order buffer)."""
        return super().gpu_bytes + self._order.size

    def sort(self, camera: Camera) -> None:
        """Upload the back-to-front order for ``camera`` if its view differs from the last one."""
        key = camera.view_key()
        if key == self._view_key:
            return
        t0 = time.perf_counter()
        order = front_to_back(self.scene.means, camera)[::-1]
        self.stats.sort_ms = (time.perf_counter() - t0) * 1e3
        self.set_order(order, key)

    def set_order(self, back_to_front: np.ndarray, view_key: bytes | None = None) -> None:
        """Use a draw order computed elsewhere (e.g. by the viewer's sort thread)."""
        if back_to_front.size:
            self._order.write(np.ascontiguousarray(back_to_front, dtype=np.uint32).tobytes())
        self._view_key = view_key

    # ---- drawing ---------------------------------------------------------------------------
    def draw(self, camera: Camera, lens: Lens, settings: RenderSettings = RenderSettings(),
             count: bool = False, sort: bool = True) -> None:
        """Splat the scene into the float targets (no read-back). Sorts only if the view moved;
        ``sort=False`` keeps the current order (the viewer sorts off its UI thread meanwhile)."""
        self._targets(camera.width, camera.height)
        if sort:
            self.sort(camera)
        self.camera, self.lens = camera, lens
        p = self.program
        set_projection_uniforms(p, camera, lens, settings)
        p["u_count"].value = count
        self._bind_scene()
        self._order.bind_to_storage_buffer(3)
        if count:
            self._counter.write(np.zeros(1, np.uint32).tobytes())
        self._counter.bind_to_storage_buffer(4)
        self.fbo.use()
        self.ctx.viewport = (0, 0, camera.width, camera.height)
        self.fbo.clear(0.0, 0.0, 0.0, 0.0)
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
        self.ctx.blend_equation = moderngl.FUNC_ADD
        if self.scene.count:
            self._vao.render(moderngl.TRIANGLE_STRIP, vertices=4, instances=self.scene.count)
        self.ctx.disable(moderngl.BLEND)
        self._encoded = self.encoded_scene and not settings.blend_linear
        if count:
            self.stats.drawn = int(np.frombuffer(self._counter.read(), np.uint32)[0])

    def _release_backend(self) -> None:
        for obj in (self._order, self._counter, self._vao, self.program):
            obj.release()
