"""The compute backend: a GPU-resident tile rasteriser in GLSL compute shaders.

Per frame, all on the GPU: (the depth sort, only when the view moved: depth keys of all Gaussians
and a radix sort, gpu_sort.py) → preprocess, one thread per Gaussian (project.glsl, the quad path's
projection, CoC and opacity normalisation; the support box → a rectangle of tiles) → count
and scan the tiles each Gaussian touches, in depth order → duplicate one (tile, Gaussian) pair per
touched tile → stable radix sort by tile (the depth order survives within each tile) → each tile's
range → list the tiles that hold some of the range of the order being drawn → blend each listed
tile front to back in one workgroup, dispatched indirectly (lens.glsl's alpha, float32, early stop at
T < 1e-4) straight into the Renderer's colour/depth targets. Only the pair count comes back to the
CPU (a 4-byte total per 256 Gaussians), to size the pair buffers (on llvmpipe also the longest tile's length, see
:data:`LLVMPIPE_RUN`). A frame whose pairs exceed the storage-buffer limit is drawn in depth slices,
each continuing the blend of the nearer ones.
"""

from __future__ import annotations

import moderngl
import numpy as np

from dofview.camera import Camera
from dofview.errors import BackendUnavailable, DofviewError
from dofview.deep import DeepSettings
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering.base import DrawOrder, Renderer
from dofview.rendering.deep_gpu import DeepWalk, passes, walk_take
from dofview.rendering.depth_order import order_key
from dofview.rendering.gl import compute_shader
from dofview.rendering.gpu_sort import (
    GpuRadixSort,
    groups,
    max_buffer_bytes,
    require_compute,
)
from dofview.rendering.tile_marks import MARKS_BINDING, TileMarks
from dofview.rendering.uniforms import set_projection_uniforms
from dofview.scene import GaussianScene

LLVMPIPE_SHAPE = (8, 2)
"""(tile side, pixels per thread along a side) on Mesa llvmpipe: measured fastest there of 8×2, 16×2,
16×4, 32×4 at 1M Gaussians, 1200×675 (docs/BENCHMARKS.md "Compute backend"): on a CPU the
evaluations of ~1-pixel splats over a whole tile dominate, and a thread blending 2×2 pixels loads
each splat once for four of them."""
GPU_SHAPE = (16, 1)
"""(tile side, pixels per thread) elsewhere: the tile rasterisers' usual 16×16 threads; not yet
measured here (scripts/gpu_bench.sh times 16×1, 16×2, 8×1 and 32×2)."""
LLVMPIPE_RUN = 60_000
"""Loop iterations one blend pass may take on llvmpipe, which ends an invocation's loops after
65535 iterations in all (a pass takes LLVMPIPE_RUN / (pix² + 1) splats of a tile; a longer tile
is blended in passes)."""
SPLAT_BYTES = 48  # glsl/splat_record.glsl: Splat
_NO_TILES = np.array([0, 0, 1, 0], np.uint32).tobytes()  # a dispatch of no workgroups, none listed
PER_GAUSSIAN_BYTES = SPLAT_BYTES + 8 + 4 + 4  # splat, tile rectangle, order, tile count (= depth key)
"""GPU bytes per Gaussian that this backend adds to the scene's buffers (besides the pair buffers)."""


class ComputeBackend(Renderer):
    """The compute tile rasteriser (see the module docstring; :class:`Renderer` for the arguments).

    Args:
        max_pairs: most (tile, Gaussian) pairs per depth slice (default and ceiling: what one
            storage buffer holds).
        tile, pix: tile side in pixels and pixels per thread along a side (default: by device,
            :data:`LLVMPIPE_SHAPE` or :data:`GPU_SHAPE`).

    Raises:
        BackendUnavailable: the GL lacks compute shaders (OpenGL < 4.3).
        DofviewError: the scene's per-Gaussian buffers exceed this GL's storage-buffer limit.
    """

    name = "compute"

    @classmethod
    def require(cls, ctx: moderngl.Context, count: int = 0) -> None:
        """Compute shaders with storage buffers (OpenGL 4.3), and a splat buffer for ``count``
        Gaussians within the storage-buffer limit."""
        super().require(ctx, count)
        require_compute(ctx)
        limit, n = max_buffer_bytes(ctx), max(count, 1)
        if SPLAT_BYTES * n > limit:
            raise DofviewError(f"{count} Gaussians need a {SPLAT_BYTES * n / 2**20:.0f} MiB splat buffer; this "
                               f"OpenGL binds at most {limit / 2**20:.0f} MiB (use --raster quad)")

    def __init__(self, scene: GaussianScene, ctx: moderngl.Context | None = None, packed: bool = True,
                 max_pairs: int | None = None, tile: int | None = None, pix: int | None = None) -> None:
        super().__init__(scene, ctx, packed)
        self.limit = max_buffer_bytes(self.ctx)
        n = max(scene.count, 1)  # GL refuses zero-sized buffers
        self.max_pairs = min(max_pairs or self.limit // 4, self.limit // 4)
        """Most (tile, Gaussian) pairs one pass holds; a frame with more is drawn in depth slices."""
        llvmpipe = "llvmpipe" in self.ctx.info["GL_RENDERER"]
        shape = LLVMPIPE_SHAPE if llvmpipe else GPU_SHAPE
        self.tile, self.pix = tile or shape[0], pix or (shape[1] if tile is None else 1)
        """Tile side in pixels; pixels per blend thread along a side (a workgroup of
        (tile / pix)² threads blends one tile, each thread pix × pix pixels)."""
        if self.tile % self.pix:
            raise DofviewError(f"tile side {self.tile} must be a multiple of the pixels per thread {self.pix}")
        self.loop_limit = LLVMPIPE_RUN if llvmpipe else None
        """Most loop iterations one invocation may run (None: no limit)."""
        self.sorter = GpuRadixSort(self.ctx)
        defs = self.shader_defines
        self._keys_prog = compute_shader(self.ctx, "sort_depth_keys.comp", defs)
        self._pre = compute_shader(self.ctx, "tiles_preprocess.comp", {**defs, "TILE": f"{self.tile}u"})
        tile_def = {"TILE": f"{self.tile}u"}
        self._count = compute_shader(self.ctx, "tiles_count.comp", tile_def)
        self._dup = compute_shader(self.ctx, "tiles_duplicate.comp", tile_def)
        self._ranges_prog = compute_shader(self.ctx, "tiles_ranges.comp")
        self._longest_prog = compute_shader(self.ctx, "tiles_longest.comp")
        self._window = compute_shader(self.ctx, "tiles_window.comp", {**tile_def, "MARKS_BINDING": MARKS_BINDING})
        self._blend = compute_shader(self.ctx, "tiles_blend.comp", {"GROUP": f"{self.tile // self.pix}u", "PIX": f"{self.pix}u",
                                                              **({"KERNEL_SELECT": 1} if llvmpipe else {})})
        self._capacity = 0
        self._per_gaussian_buffers(n)
        self._longest = self.ctx.buffer(reserve=4)
        self._pairs: list[moderngl.Buffer] = []  # tile keys, values, and the two sort scratch buffers
        self._pair_capacity = 0
        self._ranges: moderngl.Buffer | None = None
        self._listed: moderngl.Buffer | None = None  # a window's tiles holding pairs (tiles_window.comp)
        self._command = self.ctx.buffer(reserve=16)  # the blend's indirect dispatch over them, and their count
        self.pairs = 0
        """(tile, Gaussian) pairs of the last draw."""
        self.slices = 0
        """Depth slices the last draw needed (1 unless its pairs exceeded :attr:`max_pairs`)."""
        self._tiles = (0, 0)  # tiles across and down of the image being drawn
        self._image = (0, 0)  # its size (a guarded image's in the sliced mode)
        self._tau = 0.0
        self._binned = False  # the pairs of the last prepare_splats are made and sorted (one buffer holds them)
        self._span = (0, 0)  # the ranks the last prepare_splats projected
        self._vals: moderngl.Buffer | None = None  # the sorted pairs' ranks
        self._passes: tuple[int, int] | None = None  # (splats a blend pass takes, the longest tile) where loops are limited
        self._deep_prog: moderngl.ComputeShader | None = None  # the deep walk, compiled by the first deep image
        self._deep_walk: DeepWalk | None = None

    @property
    def gpu_bytes(self) -> int:
        """Bytes of GPU storage: the scene's buffers, the per-Gaussian buffers, and the pair and
        per-tile buffers as now allocated (they grow to the largest frame drawn)."""
        tiled = (b for b in (self._ranges, self._listed) if b is not None)
        own = (self._order, self._splats, self._rects, self._offsets, self._group_totals, *self._pairs, *tiled)
        deep = self._deep_walk.gpu_bytes if self._deep_walk is not None else 0  # (after a deep image)
        return super().gpu_bytes + sum(b.size for b in own) + self.sorter.gpu_bytes + deep

    # ---- depth order ---------------------------------------------------------------------------
    def sort(self, camera: Camera) -> None:
        """Sort all Gaussians front to back on the GPU if their depths changed (depth_order.order_key;
        nothing is read back)."""
        key = order_key(camera)
        if key == self._order_key or not self.scene.count:
            return
        n = self.scene.count
        self.bind_scene()
        set_projection_uniforms(self._keys_prog, camera, Lens(), RenderSettings())
        self._keys_prog["u_n"].value = n
        self._depth_keys.bind_to_storage_buffer(3)
        self._order.bind_to_storage_buffer(4)
        self._keys_prog.run(*groups(-(-n // 256)))
        self.ctx.memory_barrier()
        scratch = self._pair_buffers(n)[2:]
        out = self.sorter.sort(self._depth_keys, self._order, n, 32, *scratch)
        assert out[1] is self._order  # four passes: the result is back in the input pair
        self._order_key = key

    def front_to_back(self) -> np.ndarray:
        """(N,) uint32 the current depth order, read back (neither mode reads it: the sliced mode
        plans its layers on the GPU, :meth:`draw_order`)."""
        if not self.scene.count:  # GL maps no zero-sized range
            return np.zeros(0, np.uint32)
        return np.frombuffer(self._order.read(size=4 * self.scene.count), np.uint32).copy()

    def draw_order(self, camera: Camera) -> DrawOrder:
        """The order buffer, nearest first, sorted for ``camera`` once :meth:`sort` ran for it."""
        return DrawOrder(self._order, False, order_key(camera) == self._order_key)

    # ---- buffers -------------------------------------------------------------------------------
    def _per_gaussian_buffers(self, n: int) -> None:
        """The order, splat, tile-rectangle, offset and scan buffers for ``n`` Gaussians (kept when
        they hold that many)."""
        if n <= self._capacity:
            return
        if self._capacity:
            for b in (self._order, self._splats, self._rects, self._offsets, self._group_totals):
                b.release()
        self._order = self.ctx.buffer(reserve=4 * n)
        self._splats = self.ctx.buffer(reserve=SPLAT_BYTES * n)
        self._rects = self.ctx.buffer(reserve=8 * n)
        self._offsets = self.ctx.buffer(reserve=4 * (n + 1))
        self._depth_keys = self._offsets  # the sort's keys, dead once sorted: the counts reuse them
        self._group_totals = self.ctx.buffer(reserve=4 * -(-(n + 1) // 256))
        self._capacity = n

    def _scene_swapped(self, order: tuple[Camera, np.ndarray] | None) -> None:
        """Per-Gaussian buffers for the new count; ``order`` written as the order of its camera's view."""
        self._per_gaussian_buffers(max(self.scene.count, 1))
        self._binned = False
        if order is not None and self.scene.count:
            camera, ftb = order
            self._order.write(np.ascontiguousarray(ftb, dtype=np.uint32))
            self._order_key = order_key(camera)

    def _pair_buffers(self, pairs: int) -> list[moderngl.Buffer]:
        """Tile keys, values and sort scratch for ``pairs`` pairs (grown by half again, never past
        the storage-buffer limit)."""
        if pairs > self._pair_capacity:
            for b in self._pairs:
                b.release()
            cap = max(pairs, min(pairs * 3 // 2, self.limit // 4))
            self._pairs = [self.ctx.buffer(reserve=4 * cap) for _ in range(4)]
            self._pair_capacity = cap
        return self._pairs

    # ---- drawing -------------------------------------------------------------------------------
    def prepare_splats(self, camera: Camera, lens: Lens, settings: RenderSettings, count: bool = False,
                       span: tuple[int, int] | None = None) -> None:
        """Preprocess and scan the tile counts of the Gaussians of ``span`` (the whole order when
        None; no read-back but the pair totals); the pairs are made and sorted by the first
        :meth:`splat_range` that follows. A span matters in the sliced mode: its huge-CoC layers
        are drawn blurred by the lens, and binning every Gaussian of the scene so blurred, to draw
        those few, cost more than the rest of its blending (docs/BENCHMARKS.md, "Cost in rooms")."""
        n = self.scene.count
        first, end = span or (0, n)
        if not 0 <= first <= end <= n:
            raise ValueError(f"span {span} is not within the order's {n} Gaussians")
        self._span = first, end
        self._tiles = (-(-camera.width // self.tile), -(-camera.height // self.tile))
        self._image = (camera.width, camera.height)
        self._tau = settings.tau
        self.pairs = 0
        self._binned = False
        if end > first:
            self._preprocess(camera, lens, settings, count, self._tiles)
            self.pairs = self._scan_counts(n)
        self._ranges_for(self._tiles)

    def splat_range(self, first: int, end: int, target: moderngl.Framebuffer,
                    box: tuple[int, int, int, int] | None = None, marks: TileMarks | None = None) -> None:
        """Rasterise Gaussians [first, end) of the depth order into ``target``'s textures, writing
        the pixels of ``box`` (image pixels (x0, y0, x1, y1), rows from the top; None: the image).
        When all pairs fit one buffer they are made and sorted once per :meth:`prepare_splats` and
        every range blends its part of each tile's list; otherwise the range is drawn in depth
        slices, each binned on its own (its pair offsets come back: 8 bytes)."""
        if not self._span[0] <= first <= end <= self._span[1] and end > first:
            raise ValueError(f"range [{first}, {end}) is outside the prepared span {self._span}")
        width, height = self._image
        x0, y0, x1, y1 = box or (0, 0, width, height)
        pixels = (x0, height - y1, x1, height - y0)  # GL rows
        tiles = self._tile_rect(pixels)
        w = self._window
        w["u_mark"].value = marks is not None
        if marks is not None:  # each listed tile marks those it shares pixels with
            w["u_mark_size"].value = marks.size
            w["u_mark_columns"].value = marks.columns
            w["u_mark_tiles"].value = (pixels[0] // marks.size, pixels[1] // marks.size,
                                       -(-pixels[2] // marks.size), -(-pixels[3] // marks.size))
        if self.pairs <= self.max_pairs:
            if not self._binned:
                self._bin(*self._span, 0, self.pairs)
                self._binned = True
            self.slices = 1
            self._blend_window(first, end, target, tiles, pixels, marks, resume=False)
            return
        if end > first:
            base = int(np.frombuffer(self._offsets.read(size=4, offset=4 * first), np.uint32)[0])
            pairs = int(np.frombuffer(self._offsets.read(size=4, offset=4 * end), np.uint32)[0]) - base
        else:
            base = pairs = 0
        slices = self._slices(first, end, base, pairs) if pairs else [(first, first, 0, 0)]
        self.slices = len(slices)
        for i, (s_first, s_end, s_base, s_pairs) in enumerate(slices):
            self._bin(s_first, s_end, s_base, s_pairs)
            self._blend_window(s_first, s_end, target, tiles, pixels, marks, resume=i > 0)

    def _tile_rect(self, pixels: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
        """The tiles (tx0, ty0, tx1, ty1) that cover ``pixels`` (x0, y0, x1, y1), rows of tiles and
        of pixels from the bottom as the targets store them."""
        tx, ty = self._tiles
        x0, y0, x1, y1 = pixels
        return (max(x0, 0) // self.tile, max(y0, 0) // self.tile, min(-(-x1 // self.tile), tx),
                min(-(-y1 // self.tile), ty))

    def _preprocess(self, camera: Camera, lens: Lens, settings: RenderSettings, count: bool,
                    tiles: tuple[int, int]) -> None:
        p = self._pre
        first, end = self._span
        set_projection_uniforms(p, camera, lens, settings)
        # a part of the order: its Gaussians, found through it (the whole scene: in storage order)
        p["u_ranked"].value = end - first < self.scene.count
        p["u_first"].value = first
        p["u_n"].value = end - first
        p["u_count"].value = count
        p["u_tiles"].value = tiles
        self.bind_scene()
        self._splats.bind_to_storage_buffer(3)
        self._rects.bind_to_storage_buffer(4)
        self._counter.bind_to_storage_buffer(5)
        self._order.bind_to_storage_buffer(6)
        p.run(*groups(-(-(end - first) // 256)))
        self.ctx.memory_barrier()

    def _scan_counts(self, n: int) -> int:
        """Tiles touched per Gaussian in depth order, scanned to first-pair offsets; the total
        (added up on the CPU from the per-workgroup totals, exact: the GPU scan is uint32)."""
        self._group_totals.clear()
        for binding, buf in enumerate((self._order, self._rects, self._offsets, self._group_totals, self._splats)):
            buf.bind_to_storage_buffer(binding)
        self._count["u_n"].value = n
        self._count["u_span"].value = self._span
        self._count.run(*groups(-(-(n + 1) // 256)))
        self.ctx.memory_barrier()
        total = int(np.frombuffer(self._group_totals.read(), np.uint32).sum(dtype=np.int64))
        if total >= 2**32:
            raise DofviewError(f"this view needs {total} (tile, Gaussian) pairs, more than the compute backend "
                               "addresses (2^32); use --raster quad or a smaller aperture")
        self.sorter.scan.run(self._offsets, n + 1)
        return total

    def _slices(self, first: int, end: int, base: int, total: int) -> list[tuple[int, int, int, int]]:
        """Depth slices (first, end Gaussian in depth order, first pair, pairs) of Gaussians
        [first, end) (pairs from ``base``) whose pairs fit :attr:`max_pairs`. The offsets are read
        back only when there is more than one."""
        if total <= self.max_pairs:
            return [(first, end, base, total)]
        offsets = np.frombuffer(self._offsets.read(size=4 * (end - first + 1), offset=4 * first),
                                np.uint32).astype(np.int64)
        if np.any(np.diff(offsets) > self.max_pairs):
            raise DofviewError(f"one Gaussian covers more than {self.max_pairs} tiles; this OpenGL's storage buffers "
                               "are too small for the compute backend (use --raster quad)")
        slices, at = [], 0
        while at < end - first:
            stop = int(np.searchsorted(offsets, offsets[at] + self.max_pairs, side="right")) - 1
            stop = end - first if stop >= end - first else stop
            slices.append((first + at, first + stop, int(offsets[at]), int(offsets[stop] - offsets[at])))
            at = stop
        return slices

    def _ranges_for(self, tiles: tuple[int, int]) -> None:
        """Each tile's range of pairs, and the list of a window's tiles (:meth:`_blend_window`)."""
        size = 8 * tiles[0] * tiles[1]
        if self._ranges is None or self._ranges.size != size:
            for buf in (self._ranges, self._listed):
                if buf is not None:
                    buf.release()
            self._ranges = self.ctx.buffer(reserve=size)
            self._listed = self.ctx.buffer(reserve=2 * size)

    def _bin(self, first: int, end: int, base: int, pairs: int) -> None:
        """Duplicate and sort the pairs of Gaussians [first, end) of the depth order (pairs from
        ``base``) by tile, and find each tile's range (and, where loops are limited, the longest)."""
        tiles = self._tiles
        keys, vals, *scratch = self._pair_buffers(max(pairs, self.scene.count, 1))
        if pairs:
            d = self._dup
            d["u_first"].value = first
            d["u_n"].value = end - first
            d["u_base"].value = base
            d["u_tiles_x"].value = tiles[0]
            run = self.loop_limit if self.loop_limit is not None and tiles[0] * tiles[1] > self.loop_limit else None
            d["u_take"].value = run or 0xFFFFFFFF
            for skip in range(0, tiles[0] * tiles[1] if run else 1, run or 1):  # passes: see LLVMPIPE_RUN
                d["u_skip"].value = skip
                for binding, buf in enumerate((self._order, self._rects, self._offsets, keys, vals, self._splats)):
                    buf.bind_to_storage_buffer(binding)
                d.run(*groups(-(-(end - first) // 256)))
                self.ctx.memory_barrier()
            bits = max((tiles[0] * tiles[1] - 1).bit_length(), 1)
            keys, vals = self.sorter.sort(keys, vals, pairs, bits, *scratch)
        self._vals = vals
        self._ranges.clear()
        if pairs:
            keys.bind_to_storage_buffer(0)
            self._ranges.bind_to_storage_buffer(1)
            self._ranges_prog["u_n"].value = pairs
            self._ranges_prog.run(*groups(-(-pairs // 256)))
            self.ctx.memory_barrier()
        take = self.loop_limit // (self.pix ** 2 + 1) if self.loop_limit is not None else None  # splats a pass
        self._passes = (take, self._longest_range(tiles)) if take is not None and pairs > take else None

    def _blend_window(self, first: int, end: int, target: moderngl.Framebuffer, tiles: tuple[int, int, int, int],
                      pixels: tuple[int, int, int, int], marks: TileMarks | None, resume: bool) -> None:
        """Blend the binned pairs of ranks [first, end) into ``target``'s colour and depth-sum
        textures, in ``tiles``, writing ``pixels`` (x0, y0, x1, y1, GL rows) of them: the tiles
        that hold some are listed first (tiles_window.comp, which marks them in ``marks`` too) and
        only they are dispatched, indirectly from the count the GPU wrote."""
        tx0, ty0, tx1, ty1 = tiles
        if tx1 <= tx0 or ty1 <= ty0:
            return
        self._command.write(_NO_TILES)
        w = self._window
        w["u_tiles"].value = tiles
        w["u_tiles_x"].value = self._tiles[0]
        w["u_window"].value = (first, end)
        self._vals.bind_to_storage_buffer(1)
        self._ranges.bind_to_storage_buffer(2)
        self._listed.bind_to_storage_buffer(5)
        self._command.bind_to_storage_buffer(6)
        if marks is not None:
            marks.buffer.bind_to_storage_buffer(MARKS_BINDING)
        w.run(-(-(tx1 - tx0) // 8), -(-(ty1 - ty0) // 8))
        self.ctx.memory_barrier()
        colour, depth = target.color_attachments[:2]
        colour.bind_to_image(0, read=True, write=True)
        depth.bind_to_image(1, read=True, write=True)
        b = self._blend
        b["u_tau"].value = self._tau
        b["u_box"].value = pixels
        take, longest = self._passes or (None, 1)
        b["u_take"].value = take or 0xFFFFFFFF
        for skip in range(0, longest, take or 1):
            b["u_skip"].value = skip
            b["u_resume"].value = resume or skip > 0
            self._splats.bind_to_storage_buffer(0)
            self._order.bind_to_storage_buffer(3)
            b.run_indirect(self._command)
            self.ctx.memory_barrier()

    def _longest_range(self, tiles: tuple[int, int]) -> int:
        """The most pairs any tile holds (a 4-byte read-back)."""
        self._longest.write(np.zeros(1, np.uint32).tobytes())
        self._ranges.bind_to_storage_buffer(0)
        self._longest.bind_to_storage_buffer(1)
        self._longest_prog["u_n"].value = tiles[0] * tiles[1]
        self._longest_prog.run(*groups(-(-tiles[0] * tiles[1] // 256)))
        self.ctx.memory_barrier()
        return int(np.frombuffer(self._longest.read(), np.uint32)[0])

    # ---- deep image ----------------------------------------------------------------------------
    def _deep(self, camera: Camera, lens: Lens, settings: RenderSettings, deep: DeepSettings,
              encoded: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each pixel's splats walked from the tile lists the blend uses (glsl/deep_tiles.comp),
        binned once, or per depth slice (walked one after another) when the pairs exceed a buffer."""
        if self._deep_prog is None:
            self._deep_prog = compute_shader(self.ctx, "deep_tiles.comp", {"TILE": self.tile})
            self._deep_walk = DeepWalk(self.ctx)
        self.prepare_splats(camera, lens, settings, False)
        slices = self._slices(0, self.scene.count, 0, self.pairs) if self.pairs else [(0, 0, 0, 0)]
        prog, walker, take = self._deep_prog, self._deep_walk, walk_take(self.ctx)
        prog["u_tau"].value = settings.tau
        prog["u_tiles_x"].value = self._tiles[0]
        prog["u_size"].value = (camera.width, camera.height)
        binned = -1  # the slice whose pairs are binned now

        def walk(r0: int, r1: int, emit: bool) -> None:
            nonlocal binned
            rows = ((camera.height - r1) // self.tile, -(-(camera.height - r0) // self.tile))  # its tile rows (GL)
            for i, piece in enumerate(slices):
                if binned != i:
                    self._bin(*piece)
                    binned = i
                runs = passes(self._longest_range(self._tiles) if take is not None else 0, take)
                for j, (skip, n) in enumerate(runs):
                    walker.set_pass(prog, resume=i > 0 or j > 0, last=i == len(slices) - 1 and j == len(runs) - 1)
                    prog["u_rows"].value = (r0, r1)
                    prog["u_tile_row0"].value = rows[0]
                    prog["u_skip"].value = skip
                    prog["u_take"].value = n
                    for binding, buf in enumerate((self._splats, self._vals, self._ranges, self._order)):
                        buf.bind_to_storage_buffer(binding)
                    prog.run(self._tiles[0], rows[1] - rows[0])
                    self.ctx.memory_barrier()

        bands = walker.count_bands(np.zeros(camera.height), camera.width, "pixels")
        return walker.run(prog, camera.width, camera.height, deep, encoded, walk, bands)

    def _release_backend(self) -> None:
        for obj in (self._order, self._splats, self._rects, self._offsets, self._group_totals,
                    self._longest, *self._pairs, self._ranges, self._listed, self._command, self._keys_prog, self._pre,
                    self._count, self._dup, self._ranges_prog, self._longest_prog, self._window, self._blend,
                    self._deep_prog, self._deep_walk):
            if obj is not None:
                obj.release()
        self.sorter.release()


__all__ = ["ComputeBackend", "BackendUnavailable", "PER_GAUSSIAN_BYTES"]
