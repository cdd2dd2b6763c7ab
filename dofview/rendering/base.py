"""The renderer contract every backend meets, and what all backends share: the scene's storage
buffers, the float targets a frame is drawn into, the read-back and the display (tone-mapping) pass.

:meth:`Renderer.draw` is one template for every backend: size the targets, bring the draw order
up to date (:meth:`Renderer.sort`, each backend its own way), set camera and lens, run the
backend's splatting step (:meth:`Renderer.splat_scene`: :meth:`~Renderer.prepare_splats`, then
:meth:`~Renderer.splat_range` over the whole order; ``RenderSettings.dof == "sliced"`` instead
blends contiguous ranges of that order as depth slices, rendering/sliced.py), record whether the
targets hold display-encoded colour (:attr:`Renderer.targets_encoded`) and the counters
(:attr:`Renderer.stats`). A backend implements :meth:`~Renderer.require` (probed before the scene is
uploaded), :meth:`~Renderer.sort`, :meth:`~Renderer.front_to_back`, :meth:`~Renderer.draw_order`,
:meth:`~Renderer.prepare_splats` and :meth:`~Renderer.splat_range`; the viewer, the CLI, the
benchmark, progressive refinement, the sliced mode and the tests use only the public methods here,
so any backend serves all of them. Backends are named in one place, :data:`dofview.rendering.BACKENDS`.

The layer-drawing steps (what the sliced mode draws a frame with): :meth:`Renderer.prepare_splats`
sets up a camera, lens and settings, :meth:`Renderer.splat_range` blends a contiguous range of the
draw order into a target within a box, :meth:`Renderer.splat_scene` draws the whole order into the
renderer's targets, and :meth:`Renderer.draw_order` hands GPU kernels the order where the backend
keeps it, with :meth:`Renderer.bind_scene` binding the scene's storage buffers for them.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

import moderngl
import numpy as np

from dofview.camera import Camera
from dofview.deep import DeepFrame, DeepSettings
from dofview.frame import Frame, RenderSettings, depth_from_weighted
from dofview.lens import Lens
from dofview.rendering.display import DisplayPass
from dofview.errors import BackendUnavailable
from dofview.rendering.gl import GL_REQUIRED, check_size, float32_uniform, headless_context
from dofview.rendering.packing import colour_scale, gpu_arrays
from dofview.rendering.slices import Layer, LensCell, SliceRule
from dofview.rendering.tile_marks import MARKS_BINDING, TileMarks
from dofview.scene import GaussianScene
from dofview.tonemap import Tonemap, decode
from dofview.tonemap.stats import Stats

UPLOAD_CHUNK = 1 << 16  # Gaussians packed and uploaded per step; even, so packed SH halves stay word-aligned


@dataclass(frozen=True)
class DrawOrder:
    """The draw order on the GPU (:meth:`Renderer.draw_order`).

    Attributes:
        buffer: (N,) uint32 scene indices, a storage buffer.
        back_to_front: it holds the farthest first (the quad backend blends in that order); else
            the nearest first.
        sorted: it is sorted for the depths of the camera asked about (depth_order.order_key);
            else it is an earlier view's (the quad backend's background sort is still running),
            and nearly sorted.
    """

    buffer: moderngl.Buffer
    back_to_front: bool
    sorted: bool


@dataclass
class DrawStats:
    """What the renderer counts: Gaussians drawn by the last counted draw (not culled), total, the
    last sort's time in ms and the views sent to a background sort (:meth:`Renderer.request_order`)."""

    drawn: int = 0
    total: int = 0
    sort_ms: float = 0.0
    sort_requests: int = 0


class Renderer(ABC):
    """Renders one :class:`GaussianScene` with depth of field into float targets.

    Targets: ``colour_tex`` (H, W) RGBA32F, linear premultiplied RGB (display-encoded for sRGB
    scenes unless blending in linear light) and coverage; ``depth_tex`` (H, W) RGBA32F holding
    Σ w·z, Σ w/z, –, Σ w with w = α·T the blending weight of each splat.

    Args:
        scene: the scene; its arrays are uploaded once.
        ctx: a moderngl context (the viewer's window context); headless EGL when omitted.
        packed: store attributes packed (≤ 128 B per Gaussian at SH degree 3, see packing.py)
            rather than in float32.
    """

    name = "base"

    def __init__(self, scene: GaussianScene, ctx: moderngl.Context | None = None, packed: bool = True) -> None:
        self.ctx = ctx or headless_context()
        self.require(self.ctx, scene.count)  # before anything is uploaded
        self.scene = scene
        self._encoded = self.encoded_scene
        self.stats = DrawStats(total=scene.count)
        self._counter = self.ctx.buffer(reserve=4)  # Gaussians drawn, counted by the splatting step
        self._order_key: bytes | None = None  # depth_order.order_key of the view the draw order was sorted for
        self.packed = packed
        self.colour_scale = colour_scale(scene) if packed else 1.0
        self._buffers = self._upload(scene, packed, self.colour_scale)
        self.shader_defines = {"SH_DEGREE": scene.sh_degree, "SH_REST": (scene.sh_degree + 1) ** 2 - 1,
                               "FETCH": "fetch_packed.glsl" if packed else "fetch_full.glsl",
                               "COLOUR_SCALE": repr(self.colour_scale), "MARKS_BINDING": MARKS_BINDING}
        self._display = DisplayPass(self.ctx)
        self._size: tuple[int, int] | None = None
        self.camera: Camera | None = None
        self.lens: Lens | None = None
        self._sliced = None  # rendering/sliced.py's SlicedDof, made by the first sliced draw
        self.slice_rule: SliceRule | None = None
        """The sliced mode's slicing (slices.SliceRule); None: slices.rule_for the aperture (the
        benchmark compares others)."""

    @classmethod
    def require(cls, ctx: moderngl.Context, count: int = 0) -> None:
        """Raise :class:`BackendUnavailable` unless ``ctx`` can run this backend for a scene of
        ``count`` Gaussians: a probe of the GL's capabilities, made before a scene is uploaded."""
        if ctx.version_code < GL_REQUIRED:
            need, have = (f"{v // 100}.{v % 100 // 10}" for v in (GL_REQUIRED, ctx.version_code))
            raise BackendUnavailable(f"the {cls.name} backend needs OpenGL {need} (storage buffers); "
                                     f"this context is {have}")

    @property
    def encoded_scene(self) -> bool:
        """The scene's blended values are display-encoded (``scene.colour_space``, which the viewer
        lets the user change, is read at each draw)."""
        return self.scene.colour_space == "srgb"

    @property
    def sliced_layers(self) -> list[Layer]:
        """The layers of the last sliced draw (slices.plan_layers), front to back."""
        return self._sliced.layers if self._sliced is not None else []

    @property
    def sliced_bytes(self) -> int:
        """GPU bytes of the sliced mode's targets as now allocated (0 before its first draw)."""
        return self._sliced.gpu_bytes if self._sliced is not None else 0

    @property
    def targets_encoded(self) -> bool:
        """The colour in the targets is display-encoded (an sRGB scene blended as trained), else linear."""
        return self._encoded

    # ---- buffers ---------------------------------------------------------------------------
    def _upload(self, scene: GaussianScene, packed: bool, scale: float,
                arrays: dict[int, np.ndarray] | None = None) -> dict[int, moderngl.Buffer]:
        """The scene's storage buffers by binding, packed and written UPLOAD_CHUNK Gaussians at a time:
        host memory holds one chunk's packed copy, not the whole scene's (issue 7: a load peaks at
        ≤ 2× the file size). Arrays go in through the buffer protocol, without a bytes copy.
        ``arrays``: the whole scene's, packed beforehand (:func:`~dofview.rendering.packing.gpu_arrays`)."""
        if not scene.count:
            return {0: self.ctx.buffer(np.zeros(16, np.uint32))}
        if arrays is not None:
            return {b: self.ctx.buffer(np.ascontiguousarray(a)) for b, a in arrays.items()}
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

    def swap_scene(self, scene: GaussianScene, arrays: dict[int, np.ndarray] | None = None,
                   order: tuple[Camera, np.ndarray] | None = None) -> None:
        """Draw ``scene`` from now on in place of the current one, keeping the programs, targets and
        settings (the viewer swaps the chunks of a streamed LOD set it draws as the camera moves).
        ``scene`` has the current scene's SH degree (the programs are built for it); its colours are
        stored with the current :attr:`colour_scale` (beyond it they saturate).

        Work that need not hold up the caller's thread can be done before, on another thread:
        ``arrays``: ``scene``'s storage arrays, ``packing.gpu_arrays(scene, self.packed,
        self.colour_scale)``; ``order``: (camera, its (N,) front-to-back order of ``scene``,
        ``depth_order.front_to_back``), drawn for that camera's view instead of sorting it again.
        Without ``order`` the next draw sorts.

        Raises:
            DofviewError: this backend cannot hold ``scene`` (:meth:`require`: BackendUnavailable,
                or a buffer over the GL's limit); the current scene stays.
            ValueError: ``scene`` has another SH degree.
        """
        if scene.sh_degree != self.scene.sh_degree:
            raise ValueError(f"a swapped scene keeps the SH degree {self.scene.sh_degree}, not {scene.sh_degree}")
        self.require(self.ctx, scene.count)
        buffers = self._upload(scene, self.packed, self.colour_scale, arrays)
        for b in self._buffers.values():
            b.release()
        self._buffers, self.scene = buffers, scene
        self.stats.total = scene.count
        self._order_key = None
        # the sliced mode keeps nothing of the old scene (its plan's buffers grow with the count),
        # so its programs and targets stay
        self._scene_swapped(order)

    def _scene_swapped(self, order: tuple[Camera, np.ndarray] | None) -> None:
        """The backend's part of :meth:`swap_scene`, after the scene's buffers: size its own
        per-Gaussian buffers for :attr:`scene`, drop what it held of the old scene's order, and
        take ``order`` (camera, front-to-back order) as the order of that camera's view if given."""

    def bind_scene(self) -> None:
        """Bind the scene's storage buffers at the bindings the fetch_*.glsl files read (0 and 2),
        for a kernel that reads the Gaussians (the backends' own, the sliced mode's plan)."""
        for binding, buf in self._buffers.items():
            buf.bind_to_storage_buffer(binding)

    @property
    def gpu_bytes(self) -> int:
        """Bytes of per-Gaussian GPU storage (the scene's buffers and the sliced mode's plan once it
        planned a frame; backends add their own)."""
        plan = self._sliced.plan_bytes if self._sliced is not None else 0
        return sum(b.size for b in self._buffers.values()) + plan

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

    # ---- drawing: the template and the backend's part ---------------------------------------
    def draw(self, camera: Camera, lens: Lens, settings: RenderSettings = RenderSettings(),
             count: bool = False, cell: LensCell | None = None) -> None:
        """Splat the scene into ``colour_tex``/``depth_tex`` (no read-back), sorted for ``camera``
        unless its order was asked for with :meth:`request_order` and is still on its way (then with
        the last order). ``count``: also count the Gaussians drawn into ``stats.drawn``. ``cell``:
        the part of the lens the sliced mode blurs with (progressive refinement's passes; None: the
        whole aperture); the per-splat mode has no kernel shape and refuses one."""
        self._targets(camera.width, camera.height)
        self._order_for(camera)
        self.camera, self.lens = camera, lens
        if count:
            self._counter.write(np.zeros(1, np.uint32).tobytes())
        if settings.dof == "sliced":
            self._sliced_mode().draw(camera, lens, settings, count, cell)
        else:
            if cell is not None:
                raise ValueError("the per-splat mode blurs with no lens cell")
            self.splat_scene(camera, lens, settings, count)
        self._encoded = self.encoded_scene and not settings.blend_linear
        if count:
            self.stats.drawn = int(np.frombuffer(self._counter.read(), np.uint32)[0])

    # ---- the layer-drawing steps (public: the sliced mode draws its layers with them) -----------
    def splat_scene(self, camera: Camera, lens: Lens, settings: RenderSettings, count: bool = False) -> None:
        """The splatting step: the whole scene, in the current order, into :attr:`fbo`'s targets
        (sized for ``camera``: :meth:`draw` sizes them); ``count``: add the Gaussians drawn to the
        counter :meth:`draw` zeroed and reads into ``stats.drawn``."""
        self.prepare_splats(camera, lens, settings, count)
        self.fbo.clear(0.0, 0.0, 0.0, 0.0)
        self.splat_range(0, self.scene.count, self.fbo)

    @abstractmethod
    def prepare_splats(self, camera: Camera, lens: Lens, settings: RenderSettings, count: bool = False,
                       span: tuple[int, int] | None = None) -> None:
        """Set up splatting with ``camera`` (whose size is the targets' that follow), ``lens`` and
        ``settings`` for the :meth:`splat_range` calls that follow (``count``: the Gaussians of
        ``span`` that the projection keeps, or of each range as it is drawn, are added to the draw
        counter, see :meth:`splat_scene`). ``span``: (first, end) of the front-to-back order, the
        only Gaussians those calls draw (a backend may project only them; a range beyond it is a
        ValueError); None: the whole order."""

    @abstractmethod
    def splat_range(self, first: int, end: int, target: moderngl.Framebuffer,
                    box: tuple[int, int, int, int] | None = None, marks: TileMarks | None = None) -> None:
        """Blend Gaussians [first, end) of the front-to-back order, as :meth:`prepare_splats` set up,
        into ``target`` (colour and depth-sum attachments as :attr:`fbo`'s, camera-sized), whose
        pixels the caller cleared. ``box``: (x0, y0, x1, y1) image pixels (rows from the top, ends
        exclusive) outside which the range writes nothing (None: anywhere). ``marks``: the tiles
        it may write in are marked there (None: not asked)."""

    @abstractmethod
    def draw_order(self, camera: Camera) -> DrawOrder:
        """The current draw order where the backend keeps it on the GPU, for kernels that read it
        (the sliced mode's plan, rendering/layer_plan.py), and whether it is sorted for ``camera``'s
        depths."""

    @abstractmethod
    def front_to_back(self) -> np.ndarray:
        """(N,) uint32 the current draw order, nearest first, on the CPU (the sliced mode cuts it)."""

    @abstractmethod
    def sort(self, camera: Camera) -> None:
        """Bring the draw order up to date for ``camera`` now (a no-op when the view did not move)."""

    def forget_order(self) -> None:
        """Drop the draw order, so that the next draw sorts afresh (a benchmark times that sort)."""
        self._order_key = None

    def _order_for(self, camera: Camera) -> None:
        """The order step of :meth:`draw` (backends that sort in the background override it)."""
        self.sort(camera)

    def request_order(self, camera: Camera) -> bool:
        """Ask for the draw order of ``camera``'s view without waiting (the viewer, every frame): a
        backend whose sort is slow sorts in the background and :meth:`draw` uses the last order until
        the new one is in; the others sort now. True when a background sort finished and its order
        was taken in since the last call (what was drawn with the older order is stale)."""
        self.sort(camera)
        return False

    @property
    def sort_pending(self) -> bool:
        """An order asked for with :meth:`request_order` is still on its way."""
        return False

    def fill_targets(self, write: Callable[[moderngl.Framebuffer], None], encoded: bool, camera: Camera,
                     lens: Lens) -> None:
        """Put an image made elsewhere (progressive refinement's average) into the targets, so that
        :meth:`read` and the display pass serve it like a draw: ``write`` draws it into :attr:`fbo`
        (colour, depth sums); ``encoded``: its colour is display-encoded; ``camera``, ``lens``: the
        view it shows (the focus aid reads the lens)."""
        self._targets(camera.width, camera.height)
        write(self.fbo)
        self._encoded = encoded
        self.camera, self.lens = camera, lens

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

    # ---- deep image --------------------------------------------------------------------------
    def deep(self, camera: Camera, lens: Lens = Lens(1.0, 0.0), settings: RenderSettings = RenderSettings(),
             deep: DeepSettings = DeepSettings()) -> DeepFrame:
        """The deep image of what :meth:`render` draws with the same arguments: each pixel's splats
        front to back as deep samples (dofview.deep: merged within ``deep.tolerance``, at most
        ``deep.cap``), found and walked on the GPU by the backend (:meth:`_deep`) and read back;
        with the sliced depth of field and an aperture, the blurred layers as samples over their
        depth ranges, read back as the frame is drawn (rendering/deep_sliced.py; the frame stays in
        the targets, :meth:`read` gives it). Flattening it gives :meth:`render`'s image
        (tests/test_deep.py, tests/test_deep_sliced.py: ≥ 50 dB)."""
        self._targets(camera.width, camera.height)
        self.sort(camera)
        encoded = self.encoded_scene and not settings.blend_linear
        if settings.dof == "sliced" and lens.aperture > 0:
            image = self._sliced_deep(camera, lens, settings, deep, encoded)
            if image is not None:
                return image
        counts, colour, depth = self._deep(camera, lens, settings, deep, encoded)
        return DeepFrame(counts, colour, depth)

    def _sliced_mode(self):
        """The sliced mode (rendering/sliced.py's SlicedDof), made on first use: its shaders compile then."""
        if self._sliced is None:
            from dofview.rendering.sliced import SlicedDof

            self._sliced = SlicedDof(self)
        return self._sliced

    def sliced_pass_times(self, camera: Camera, lens: Lens, settings: RenderSettings) -> dict[str, float]:
        """Draw the sliced frame (as :meth:`draw` with ``settings.dof`` "sliced"), waiting for the
        GL after each kind of pass: wall ms per kind ("plan", "blend", "gather", …: rendering/
        sliced.py; "other": what follows the resolve). The pass profile of
        ``python -m dofview.bench.sliced_study passes``; the waits make the frame slower than a
        :meth:`draw`, so its sum is not a frame time."""
        if settings.dof != "sliced":
            raise ValueError(f"a pass profile is of the sliced mode, not {settings.dof!r}")
        sliced = self._sliced_mode()
        times: dict[str, float] = {}
        last = 0.0

        def lap(kind: str) -> None:
            nonlocal last
            self.ctx.finish()
            now = time.perf_counter()
            times[kind] = times.get(kind, 0.0) + (now - last) * 1e3
            last = now

        self.ctx.finish()
        last = time.perf_counter()
        sliced.timer = lap
        try:
            self.draw(camera, lens, settings)
        finally:
            sliced.timer = None
        lap("other")
        return times

    def _sliced_deep(self, camera: Camera, lens: Lens, settings: RenderSettings, deep: DeepSettings,
                     encoded: bool) -> DeepFrame | None:
        """The sliced mode's deep image, drawn with a capture of its layers (None where its plan
        was the pinhole's: every Gaussian in focus, drawn unblurred)."""
        from dofview.rendering.deep_sliced import SliceCapture, layer_depths

        sliced = self._sliced_mode()
        capture = SliceCapture(camera.width, camera.height, lambda: sliced.guard)
        self._sliced.capture = capture
        try:
            self.draw(camera, lens, settings)
        finally:
            self._sliced.capture = None
        if self._sliced.pinhole:
            return None
        layers = self._sliced.layers
        w, h = self._size
        resolved = np.frombuffer(self.colour_tex.read(), np.float32).reshape(h, w, 4)[::-1]
        depths = layer_depths(layers, self.front_to_back(), self.scene.means, camera, settings.near)
        return capture.deep(resolved, depths, deep, encoded)

    @abstractmethod
    def _deep(self, camera: Camera, lens: Lens, settings: RenderSettings, deep: DeepSettings,
              encoded: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The backend's deep walk of the current order (sorted for ``camera``): (counts (H, W),
        colours (S, 4), depths (S, 2)) as :class:`DeepFrame` holds them; ``encoded``: the blend is
        display-encoded (the samples are decoded as dofview.deep describes)."""

    # ---- display ---------------------------------------------------------------------------
    def frame_stats(self, operator, domain: tuple[float, float] | None = None) -> Stats:
        """Scene statistics of the last draw for ``operator``, from GPU histograms (a 32 KB read-back,
        not the frame); the same numbers as ``tonemap.stats.frame_stats(self.read().rgba, operator)``.
        ``domain``: the histogram operator's CDF range (log2), default the frame's [lo, hi]."""
        return self._display.stats(self.colour_tex, self._encoded, operator, domain, self.encoded_scene)

    def tonemap_to(self, target: moderngl.Framebuffer, viewport: tuple[int, int, int, int],
                   tm: Tonemap, focus_aid: bool = False, stats: Stats | None = None, same_frame: bool = False) -> None:
        """Run the display pass (Eq. 7 with ``tm.operator``) from the last draw into ``target`` at
        ``viewport``. Adaptive operators use ``stats`` (smoothed or pooled), else this frame's;
        ``same_frame``: nothing was drawn since the last call (the bilateral base layer is kept)."""
        extra = {"u_focus_aid": focus_aid, "u_aperture": self.lens.aperture if self.lens else 0.0,
                 "u_inv_focus": float32_uniform(self.lens.inv_focus) if self.lens else 0.0}
        self._display.run(self.colour_tex, self.depth_tex, self._encoded, target, viewport, tm, stats, extra, same_frame,
                          self.encoded_scene)

    def display_image(self, tm: Tonemap = Tonemap(), focus_aid: bool = False, stats: Stats | None = None) -> np.ndarray:
        """(H, W, 3) uint8: the last draw tonemapped on the GPU, as the viewer shows it."""
        w, h = self._size
        self.tonemap_to(self.display_fbo, (0, 0, w, h), tm, focus_aid, stats)
        data = np.frombuffer(self.display_fbo.read(components=3), np.uint8).reshape(h, w, 3)
        return data[::-1].copy()

    def _release_backend(self) -> None:
        """Free what the backend itself created."""

    def release(self) -> None:
        """Free the GPU objects of this renderer (the context stays)."""
        for b in self._buffers.values():
            b.release()
        self._counter.release()
        if self._sliced is not None:
            self._sliced.release()
        self._release_backend()
        self._display.release()
        if self._size is not None:
            for obj in (self.fbo, self.colour_tex, self.depth_tex, self.display_fbo, self._display_rb):
                obj.release()
