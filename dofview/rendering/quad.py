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
from dofview.deep import DeepSettings
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering.base import DrawOrder, Renderer
from dofview.rendering.deep_gpu import DeepWalk, passes, walk_take
from dofview.rendering.depth_order import front_to_back, order_key
from dofview.rendering.gl import compute_shader, load_shader, set_uniforms
from dofview.rendering.gpu_sort import GpuRadixSort, groups
from dofview.rendering.sort_thread import SortThread
from dofview.rendering.tile_marks import MARKS_BINDING, TileMarks
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
        self._requested: bytes | None = None  # the order key request_order was last asked for
        self._awaiting: bytes | None = None  # the order key whose background order is not in yet
        self._abuffer: ABuffer | None = None  # the deep image's fragment lists, made by the first deep image

    @property
    def gpu_bytes(self) -> int:
        """Bytes of per-Gaussian GPU storage (scene buffers and the order buffer; the A-buffer's
        after a deep image)."""
        return super().gpu_bytes + self._order.size + (self._abuffer.gpu_bytes if self._abuffer is not None else 0)

    # ---- depth order ---------------------------------------------------------------------------
    def sort(self, camera: Camera) -> None:
        """Sort on this thread and upload the back-to-front order for ``camera`` if its depths differ
        from those of the last view sorted (depth_order.order_key: a lens-shifted pass keeps them)."""
        key = order_key(camera)
        if key == self._order_key:
            return
        t0 = time.perf_counter()
        order = front_to_back(self.scene.means, camera)[::-1]
        self.stats.sort_ms = (time.perf_counter() - t0) * 1e3
        self._upload_order(order, key)

    def _upload_order(self, back_to_front: np.ndarray, key: bytes) -> None:
        self._host_order = np.ascontiguousarray(back_to_front, dtype=np.uint32)
        if back_to_front.size:
            self._order.write(self._host_order.tobytes())
        self._order_key = key

    def front_to_back(self) -> np.ndarray:
        """(N,) uint32 the order in the order buffer, nearest first (kept on the CPU, no read-back)."""
        return self._host_order[::-1]

    def draw_order(self, camera: Camera) -> DrawOrder:
        """The order buffer, farthest first: sorted for ``camera``, or while its background sort
        runs an earlier view's."""
        return DrawOrder(self._order, True, order_key(camera) == self._order_key)

    def _order_for(self, camera: Camera) -> None:
        if order_key(camera) != self._awaiting:  # that view's order is being sorted in the background
            self.sort(camera)

    def request_order(self, camera: Camera) -> bool:
        """Take in a finished background sort, and send ``camera``'s view to the sort thread when it
        is not the view asked for last (the first request sorts here: there is no order to draw
        with yet). Draws of the requested view meanwhile use the last order; draws of other views
        (lens-shifted passes, other cameras) sort here as before."""
        key = order_key(camera)
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
        self._upload_order(res.order, res.order_key)
        self.stats.sort_ms = res.ms
        if res.order_key == self._awaiting:
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
            self._upload_order(ftb[::-1], order_key(camera))
            self._requested = self._order_key

    # ---- drawing -------------------------------------------------------------------------------
    def prepare_splats(self, camera: Camera, lens: Lens, settings: RenderSettings, count: bool = False,
                       span: tuple[int, int] | None = None) -> None:
        """Uniforms only: each quad is projected as it is drawn (and counted then), so ``span``
        changes nothing here."""
        p = self.program
        set_projection_uniforms(p, camera, lens, settings)
        p["u_count"].value = count

    def splat_range(self, first: int, end: int, target: moderngl.Framebuffer,
                    box: tuple[int, int, int, int] | None = None, marks: TileMarks | None = None) -> None:
        self.bind_scene()
        self._order.bind_to_storage_buffer(3)
        self._counter.bind_to_storage_buffer(4)
        p = self.program
        p["u_mark"].value = marks is not None
        if marks is not None:  # each quad's first vertex marks the tiles of its bounding rectangle
            x0, y0, x1, y1 = box or (0, 0, *target.size)
            h = target.height
            p["u_mark_size"].value = marks.size
            p["u_mark_columns"].value = marks.columns
            p["u_mark_tiles"].value = (x0 // marks.size, (h - y1) // marks.size,
                                       -(-x1 // marks.size), -(-(h - y0) // marks.size))
            marks.buffer.bind_to_storage_buffer(MARKS_BINDING)
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
        if marks is not None:
            p["u_mark"].value = False

    # ---- deep image ----------------------------------------------------------------------------
    def _deep(self, camera: Camera, lens: Lens, settings: RenderSettings, deep: DeepSettings,
              encoded: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The fragments this backend blends, kept per pixel in an A-buffer (:class:`ABuffer`) and
        walked front to back."""
        if self._abuffer is None:
            self._abuffer = ABuffer(self)
        return self._abuffer.deep(camera, lens, settings, deep, encoded)

    def _release_backend(self) -> None:
        if self._thread is not None:
            self._thread.close()
        for obj in (self._order, self._vao, self.program, self._abuffer):
            if obj is not None:
                obj.release()


class ABuffer:
    """The quad backend's deep image: an A-buffer of the fragments its quads produce.

    Per frame: (1) the quads are drawn with glsl/deep_fragments.frag counting each pixel's
    fragments (the same alpha and τ cut as quads.frag); (2) band by band of image rows (each
    within deep_gpu's limits), drawn again (scissored to the band) to store every fragment's rank in
    the front-to-back order, alpha and pixel, and its splat's colour and depth; (3) sorted by rank,
    then stably by pixel (two GPU radix sorts, glsl/deep_gather.comp between them), which leaves each
    pixel's fragments together, front to back; (4) walked per pixel into deep samples
    (glsl/deep_fragments.comp, deep_gpu.DeepWalk). Fragments land in the buffers in whatever order
    the GPU runs them: the sorts, not the draw, give the order.
    """

    def __init__(self, backend: QuadBackend) -> None:
        self.backend = backend
        self.ctx = ctx = backend.ctx
        defs = backend.shader_defines
        vert = load_shader("quads.vert", defs)
        self.count = ctx.program(vertex_shader=vert, fragment_shader=load_shader("deep_fragments.frag", {"COUNT": 1}))
        self.fill = ctx.program(vertex_shader=vert, fragment_shader=load_shader("deep_fragments.frag"))
        self.vaos = [ctx.vertex_array(p, []) for p in (self.count, self.fill)]
        self.gather = compute_shader(ctx, "deep_gather.comp")
        self.walk = compute_shader(ctx, "deep_fragments.comp")
        self.sorter = GpuRadixSort(ctx)
        self.walker = DeepWalk(ctx)
        self._buffers: dict[str, moderngl.Buffer] = {}
        self._fbo: moderngl.Framebuffer | None = None

    @property
    def gpu_bytes(self) -> int:
        """Bytes of the fragment lists and the walk's buffers, as now allocated (they grow to the
        largest band drawn: at most deep_gpu.band_items fragments, 32 B each)."""
        return sum(b.size for b in self._buffers.values()) + self.walker.gpu_bytes + self.sorter.gpu_bytes

    def _buffer(self, name: str, size: int) -> moderngl.Buffer:
        buf = self._buffers.get(name)
        if buf is None or buf.size < size:
            if buf is not None:
                buf.release()
            buf = self._buffers[name] = self.ctx.buffer(reserve=max(size, 16))
        return buf

    def _draw(self, program: moderngl.Program, camera: Camera, lens: Lens, settings: RenderSettings,
              rows: tuple[int, int]) -> None:
        """Every Gaussian's quad through ``program`` (no colour written), fragments in image rows
        ``rows`` (from the top, end exclusive) only."""
        b = self.backend
        set_projection_uniforms(program, camera, lens, settings)
        set_uniforms(program, {"u_count": False, "u_first": 0, "u_n": b.scene.count,
                               "u_size": (camera.width, camera.height), "u_row0": rows[0]})
        if self._fbo is None or self._fbo.size != (camera.width, camera.height):
            if self._fbo is not None:
                self._fbo.release()
            self._fbo = self.ctx.framebuffer(color_attachments=[self.ctx.renderbuffer((camera.width, camera.height), 1,
                                                                                       dtype="f1")])
            self._fbo.color_mask = (False, False, False, False)
        b.bind_scene()
        b._order.bind_to_storage_buffer(3)
        b._counter.bind_to_storage_buffer(4)
        self._fbo.use()
        self.ctx.viewport = (0, 0, camera.width, camera.height)
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
        self.ctx.scissor = (0, camera.height - rows[1], camera.width, rows[1] - rows[0])
        if b.scene.count:
            self.vaos[program is self.fill].render(moderngl.TRIANGLE_STRIP, vertices=4, instances=b.scene.count)
        self.ctx.scissor = None
        self.ctx.memory_barrier()

    def deep(self, camera: Camera, lens: Lens, settings: RenderSettings, deep: DeepSettings,
             encoded: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        w, h, n = camera.width, camera.height, self.backend.scene.count
        counts = self._buffer("counts", 4 * w * h)
        counts.clear()
        counts.bind_to_storage_buffer(5)
        self._draw(self.count, camera, lens, settings, (0, h))
        fragments = np.frombuffer(counts.read(size=4 * w * h), np.uint32).reshape(h, w).astype(np.int64)
        self._buffer("info", 16 * max(n, 1))
        take = walk_take(self.ctx)
        band: dict[str, object] = {}

        def prepare(r0: int, r1: int) -> None:
            per_pixel = fragments[r0:r1].ravel()
            total = int(per_pixel.sum())
            segments = np.concatenate([[0], np.cumsum(per_pixel)]).astype(np.uint32)
            band.update(total=total, longest=int(per_pixel.max()) if per_pixel.size else 0)
            seg = self._buffer("segments", 4 * segments.size)
            seg.write(segments.tobytes())
            band["segments"] = seg
            if not total:
                return
            names = ("ranks", "slots", "scratch_keys", "scratch_values", "alphas", "pixels", "keys", "places")
            bufs = {k: self._buffer(k, 4 * total) for k in names}
            cursor = self._buffer("counts", 4 * per_pixel.size)
            cursor.clear()
            for binding, buf in enumerate((cursor, seg, bufs["ranks"], bufs["slots"], bufs["alphas"], bufs["pixels"],
                                           self._buffers["info"]), start=5):
                buf.bind_to_storage_buffer(binding)
            self._draw(self.fill, camera, lens, settings, (r0, r1))
            ranks, slots = self.sorter.sort(bufs["ranks"], bufs["slots"], total, max(n - 1, 1).bit_length(),
                                            bufs["scratch_keys"], bufs["scratch_values"])
            scratch = (bufs["scratch_keys"], bufs["scratch_values"])
            free = scratch if ranks is bufs["ranks"] else (bufs["ranks"], bufs["slots"])
            for binding, buf in enumerate((slots, bufs["pixels"], bufs["keys"], bufs["places"])):
                buf.bind_to_storage_buffer(binding)
            self.gather["u_n"].value = total
            self.gather.run(*groups(-(-total // 256)))
            self.ctx.memory_barrier()
            _, places = self.sorter.sort(bufs["keys"], bufs["places"], total, max(per_pixel.size - 1, 1).bit_length(),
                                         *free)
            band.update(places=places, ranks=ranks, slots=slots, alphas=bufs["alphas"])

        def walk(r0: int, r1: int, emit: bool) -> None:
            runs = passes(int(band["longest"]), take)
            for j, (skip, count) in enumerate(runs):
                self.walker.set_pass(self.walk, resume=j > 0, last=j == len(runs) - 1)
                if band["total"]:
                    for binding, name in enumerate(("places", "ranks", "slots", "alphas")):
                        band[name].bind_to_storage_buffer(binding)  # type: ignore[attr-defined]
                self._buffers["info"].bind_to_storage_buffer(4)
                band["segments"].bind_to_storage_buffer(5)  # type: ignore[attr-defined]
                self.walk["u_band"].value = (w, r1 - r0)
                self.walk["u_skip"].value = skip
                self.walk["u_take"].value = count
                self.walk.run(-(-w // 8), -(-(r1 - r0) // 8))
                self.ctx.memory_barrier()

        bands = self.walker.count_bands(fragments.sum(axis=1), w, "fragments")
        return self.walker.run(self.walk, w, h, deep, encoded, walk, bands, prepare)

    def release(self) -> None:
        for obj in (self.count, self.fill, *self.vaos, self.gather, self.walk, self.sorter, self.walker,
                    *self._buffers.values(), self._fbo):
            if obj is not None:
                obj.release()
