"""The OpenGL splatting renderer: one code path for the viewer, the CLI, the benchmark and tests.

Per-Gaussian data lives in GPU storage buffers uploaded once per scene; only the draw order is
uploaded again, and only when the view changes (lens and exposure changes re-draw without
re-sorting). One instanced draw of four-vertex quads; see shaders/splat.vert for the math.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import moderngl
import numpy as np

from .camera import Camera
from .frame import OPACITY_NORMS, Frame, RenderSettings, depth_from_weighted
from .gl import check_size, headless_context, load_shader
from .lens import Lens
from .packing import colour_scale, gpu_arrays
from .scene import GaussianScene
from .sort import front_to_back
from .tonemap import Tonemap, decode


UPLOAD_CHUNK = 1 << 16  # Gaussians packed and uploaded per step; even, so packed SH halves stay word-aligned


@dataclass
class DrawStats:
    """Counters of the last draw: Gaussians drawn (not culled), total, sort time in ms."""

    drawn: int = 0
    total: int = 0
    sort_ms: float = 0.0


def _float32(x: float) -> float:
    """Clamp to float32 range: a uniform of 1/d_f for a focus below 1e-38 would be inf, and 0·inf
    a NaN circle of confusion even with a pinhole."""
    return min(x, float(np.finfo(np.float32).max))


class Renderer:
    """Renders one :class:`GaussianScene` with depth of field into float targets.

    Args:
        scene: the scene; its arrays are uploaded once.
        ctx: a moderngl context (the viewer's window context); headless EGL when omitted.
        packed: store attributes packed (≤ 128 B per Gaussian at SH degree 3, see packing.py)
            rather than in float32.
    """

    def __init__(self, scene: GaussianScene, ctx: moderngl.Context | None = None, packed: bool = True) -> None:
        self.ctx = ctx or headless_context()
        self.scene = scene
        self.encoded_scene = scene.colour_space == "srgb"
        self.stats = DrawStats(total=scene.count)
        n = max(scene.count, 1)  # GL refuses zero-sized buffers; an empty scene draws 0 instances
        self.packed = packed
        scale = colour_scale(scene) if packed else 1.0
        self._buffers = self._upload(scene, packed, scale)
        degree = scene.sh_degree
        self._order = self.ctx.buffer(reserve=4 * n)
        self._counter = self.ctx.buffer(reserve=4)
        defines = {"SH_DEGREE": degree, "SH_REST": (degree + 1) ** 2 - 1,
                   "FETCH": "fetch_packed.glsl" if packed else "fetch_full.glsl",
                   "COLOUR_SCALE": repr(scale)}
        self.program = self.ctx.program(
            vertex_shader=load_shader("splat.vert", defines), fragment_shader=load_shader("splat.frag"))
        self._vao = self.ctx.vertex_array(self.program, [])
        self._tonemap = self.ctx.program(
            vertex_shader=load_shader("fullscreen.vert"), fragment_shader=load_shader("tonemap.frag"))
        self._tonemap_vao = self.ctx.vertex_array(self._tonemap, [])
        self._size: tuple[int, int] | None = None
        self._view_key: bytes | None = None
        self.camera: Camera | None = None
        self.lens: Lens | None = None

    # ---- buffers ---------------------------------------------------------------------------
    def _upload(self, scene: GaussianScene, packed: bool, scale: float) -> dict[int, moderngl.Buffer]:
        """The scene's storage buffers by binding, packed and written UPLOAD_CHUNK Gaussians at a time:
        host memory holds one chunk's packed copy, not the whole scene's (issue 7: a load peaks at
        ≤ 2× the file size). Arrays go in through the buffer protocol, without a bytes copy."""
        if not scene.count:
            return {0: self.ctx.buffer(np.zeros(16, np.uint32))}
        buffers: dict[int, moderngl.Buffer] = {}
        per_gaussian: dict[int, int] = {}
        for start in range(0, scene.count, UPLOAD_CHUNK):
            part = scene.subset(slice(start, start + UPLOAD_CHUNK))
            for b, a in gpu_arrays(part, packed, scale).items():
                if b not in buffers:  # the first chunk gives the bytes per Gaussian (a pad half aside)
                    per_gaussian[b] = a.nbytes // part.count
                    buffers[b] = self.ctx.buffer(reserve=-(-per_gaussian[b] * scene.count // 4) * 4)
                buffers[b].write(np.ascontiguousarray(a), offset=start * per_gaussian[b])
        return buffers

    @property
    def gpu_bytes(self) -> int:
        """Bytes of per-Gaussian GPU storage (scene buffers and the order buffer)."""
        return sum(b.size for b in self._buffers.values()) + self._order.size

    @property
    def bytes_per_gaussian(self) -> float:
        return self.gpu_bytes / max(self.scene.count, 1)

    def _targets(self, width: int, height: int) -> None:
        if self._size == (width, height):
            return
        check_size(self.ctx, width, height)
        if self._size is not None:
            for obj in (self.fbo, self.colour_tex, self.depth_tex, self.display_fbo, self._display_rb):
                obj.release()
        self.colour_tex = self.ctx.texture((width, height), 4, dtype="f4")
        self.depth_tex = self.ctx.texture((width, height), 4, dtype="f4")
        for tex in (self.colour_tex, self.depth_tex):
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.fbo = self.ctx.framebuffer(color_attachments=[self.colour_tex, self.depth_tex])
        self._display_rb = self.ctx.renderbuffer((width, height), 4)
        self.display_fbo = self.ctx.framebuffer(color_attachments=[self._display_rb])
        self._size = (width, height)

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
        for i, name in enumerate(("u_R0", "u_R1", "u_R2")):
            p[name].value = tuple(float(v) for v in camera.R[i])
        p["u_T"].value = tuple(float(v) for v in camera.T)
        if "u_eye" in p:
            p["u_eye"].value = tuple(float(v) for v in camera.centre)
        p["u_focal"].value = (camera.fx, camera.fy)
        p["u_principal"].value = (camera.cx, camera.cy)
        p["u_viewport"].value = (float(camera.width), float(camera.height))
        p["u_near"].value = settings.near
        p["u_tau"].value = settings.tau
        p["u_aperture"].value = lens.aperture
        p["u_inv_focus"].value = _float32(lens.inv_focus)
        p["u_k"].value = settings.k
        p["u_opacity_norm"].value = OPACITY_NORMS.index(settings.opacity_norm)
        p["u_blend_linear"].value = settings.blend_linear
        p["u_count"].value = count
        for binding, buf in self._buffers.items():
            buf.bind_to_storage_buffer(binding)
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

    def read(self) -> Frame:
        """Read the last draw back as a linear :class:`Frame` (rows top to bottom)."""
        w, h = self._size
        colour = np.frombuffer(self.colour_tex.read(), np.float32).reshape(h, w, 4)[::-1]
        depth = np.frombuffer(self.depth_tex.read(), np.float32).reshape(h, w, 4)[::-1]
        rgba = np.array(colour, dtype=np.float32)
        if self._encoded:
            rgba[..., :3] = decode(rgba[..., :3])
        inv = depth_from_weighted(depth[..., 1], depth[..., 3])
        focus = np.where(inv > 0, 1.0 / np.maximum(inv, 1e-30), 0.0).astype(np.float32)
        return Frame(rgba=rgba, depth=depth_from_weighted(depth[..., 0], depth[..., 3]), encoded=self._encoded,
                     focus_depth=focus)

    def render(self, camera: Camera, lens: Lens, settings: RenderSettings = RenderSettings()) -> Frame:
        """Draw and read back: the one-call API for the CLI, benchmarks and tests."""
        self.draw(camera, lens, settings)
        return self.read()

    # ---- display ---------------------------------------------------------------------------
    def tonemap_to(self, target: moderngl.Framebuffer, viewport: tuple[int, int, int, int],
                   tm: Tonemap, focus_aid: bool = False) -> None:
        """Run the display pass (Eq. 7) from the last draw into ``target`` at ``viewport``."""
        p = self._tonemap
        self.colour_tex.use(0)
        self.depth_tex.use(1)
        p["u_colour"].value = 0
        p["u_depth"].value = 1
        p["u_encoded"].value = self._encoded
        p["u_background"].value = tuple(float(c) for c in tm.background)
        p["u_exposure"].value = float(tm.exposure)
        p["u_gamma"].value = float(tm.gamma)
        p["u_focus_aid"].value = focus_aid
        p["u_aperture"].value = self.lens.aperture if self.lens else 0.0
        p["u_inv_focus"].value = _float32(self.lens.inv_focus) if self.lens else 0.0
        target.use()
        self.ctx.viewport = viewport
        self._tonemap_vao.render(moderngl.TRIANGLES, vertices=3)

    def display_image(self, tm: Tonemap = Tonemap(), focus_aid: bool = False) -> np.ndarray:
        """(H, W, 3) uint8: the last draw tonemapped on the GPU, as the viewer shows it."""
        w, h = self._size
        self.tonemap_to(self.display_fbo, (0, 0, w, h), tm, focus_aid)
        data = np.frombuffer(self.display_fbo.read(components=3), np.uint8).reshape(h, w, 3)
        return data[::-1].copy()

    def release(self) -> None:
        """Free the GPU objects of this renderer (the context stays)."""
        for b in self._buffers.values():
            b.release()
        for obj in (self._order, self._counter, self._vao, self.program, self._tonemap_vao, self._tonemap):
            obj.release()
        if self._size is not None:
            for obj in (self.fbo, self.colour_tex, self.depth_tex, self.display_fbo, self._display_rb):
                obj.release()
