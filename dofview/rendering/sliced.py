"""Sliced depth of field on the GPU (``RenderSettings.dof == "sliced"``, the default), the GL twin
of slices.py.

The backend's draw order, nearest first, is cut into contiguous layers by signed CoC
c = ½·A·(1/z − 1/d_f) px, planned on the GPU (rendering/layer_plan.py: the twin of
slices.plan_frame; the CPU reads back O(layers) numbers). Every pass works in the frame extended
by the guard band its layers need (slices.guard_band; Camera.guarded keeps the frame's frustum
clamp). Front to back, each layer is blended by the backend as a pinhole with the frame's τ
(:meth:`Renderer.splat_range`, within slices.layer_windows) into one reused slice target, marking
the 16 × 16 tiles it may write (tile_marks.TileMarks); glsl/slice_tiles.comp lists them, as runs
along each row for the passes drawn over them (slice_tiles.vert) and as tiles for those
dispatched, so that the passes at full resolution below run only there (a layer fills a third to
three quarters of its window's tiles in the shared scenes), then

1. glsl/slice_visible.comp adds its depth sums under their transmittance to the depth
   accumulator (which so ends up holding the pinhole's depth: EXR Z, click-to-focus) and keeps
   the layer's visible coverage beside them;
2. slice_reduce.frag averages it down to its level 1/s (4 × 4 or 2 × 2 a pass) and
   slice_prepare.frag gives each texel its signed blur (the CoC of its mean inverse depth) and
   divides it by the kernel's N (slice_blur.glsl);
   the slice target is emptied (slice_empty.frag) after the prepare, which reads it at full
   resolution for step 4; a layer gathered at full resolution is prepared and emptied by step 1's
   pass itself;
3. slice_gather.frag spreads every texel over the kernel at its own blur (slice_kernel.glsl: the
   aperture, or a lens cell of progressive refinement), blended front to back into the frame's
   accumulators ("over" colour, summed visible coverage), or for a reduced layer into its run's
   (the consecutive layers of one level), which slice_upsample.frag composites into the frame's
   once the run ends, in the tiles the run's gathers (slice_occupancy.comp) and sprites marked;
4. a reduced layer's highlights (slices.highlights): slice_prepare.frag appends each pixel of the
   layer's blocks whose brightness stands out of its neighbourhood to a sprite list (at most
   SliceRule.sprites of the frame's pixels, a layer's highlights all or none, so that no order of
   the GPU's chooses: sprite_accept.comp keeps them if they fit in what is left of the cap, else
   empties the layer's draw of them and has it prepared again without, so that they stay in its
   gather) and takes that light out of its texel;
   slice_sprite.vert/.frag draw them as instanced quads, indirectly from the count the GPU wrote
   (no read-back), each the gather's kernel at full resolution at the pixel's own CoC, into
   sprite targets that slice_upsample.frag adds to the layer's image. Such a layer is a run of
   its own, so that the layers behind it are hidden by its sprites too;

and slice_resolve.frag writes the frame into the renderer's targets: "over", scaled up to the
visible coverage where a cut between layers left it short, and the accumulated depth sums. The
splats blurred beyond SliceRule.huge of the frame (geometry at the lens) form a front and a back
layer drawn by the per-splat method with the lens (slices.py says why). At
A = 0 there is one layer, not blurred: the pinhole frame, drawn straight into the renderer's targets.

Only the pixels a layer's Gaussians can reach (:func:`screen_boxes`) and its blur around them are
processed. GPU memory (:attr:`SlicedDof.gpu_bytes`), per pixel of the guarded image: at full
resolution the slice colour and depth sums, the two accumulators, the depth accumulator, the
sprite targets and the prepared layer (RGBA32F ×7, R32F and RG32F: 124 B), and per reduced level s
the layer averaged down, prepared, and a run's accumulators (88/s² B): ≤ 154 B in all besides the
renderer's own targets, the sprite list (32 B a sprite: 0.64 B per pixel of frame) and the tiles'
marks and lists (32 B a tile: 0.125 B per pixel) (≈ 155 MB
per megapixel of frame without a band; the widest band, an eighth of the frame's larger side on
every side rounded up to 32 px, makes the image about 2× the frame's pixels: 266 MB per megapixel
of frame measured at 640×360 before the sprite targets, which add 20 B per pixel of that image).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import moderngl
import numpy as np

from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering.gl import compute_shader, float32_uniform, load_shader
from dofview.rendering.layer_plan import GpuLayerPlan
from dofview.rendering.slices import (
    NORM_FINE,
    NORM_SAMPLES,
    Aperture,
    Box,
    Edges,
    Layer,
    LensCell,
    SliceRule,
    frame_plan,
    has_sprites,
    pinhole_plan,
    rule_for,
    sprite_cap,
)
from dofview.rendering.tile_marks import MARKS_BINDING, TileMarks

MAX_TAPS = 256
"""Size of the shaders' tap array: a disk of up to 8.5 px at its level (slices.plan_layers: the
largest radius at a level is the rule's limit + 2, 8 with blades)."""
MAX_PLANES = 80
"""Size of the shaders' half-plane array: a 64-bladed aperture and 16 neighbouring lens cells."""
PREFIX_STEPS = 8
"""Steps per level px of slice_gather.frag's table of how many taps a tile needs, by the largest
|ρ| of the sources within its reach (slice_occupancy.comp)."""
MAX_PREFIX = 80
"""Size of that table: |ρ| up to 10 level px (the largest at a level is 8.5)."""
SPRITE_HEADER = 16
"""Bytes before the sprite list's records (the frame's count of sprites drawn, the layer's count of
highlights and whether they are drawn, padded)."""
SPRITE_BYTES = 32
"""Bytes of one sprite: its colour and (x, y, ρ, visible), two vec4 (slice_prepare.frag)."""
TILE = 16
"""Side, px, of the tiles in which a layer's passes at full resolution run: those its blend marked
(tile_marks.TileMarks; slice_tiles.comp)."""
_NO_SPRITES = np.array([4, 0, 0, 0], np.uint32).tobytes()  # a draw of 4 vertices, 0 instances
_NO_TILES = np.array([4, 0, 0, 0, 0, 0, 1, 0], np.uint32).tobytes()  # that draw, and a dispatch of none
_NOT_AGAIN = np.array([3, 0, 0, 0], np.uint32).tobytes()  # a draw of 3 vertices, 0 instances
_UNSET = object()


@functools.lru_cache(maxsize=512)  # 32 KB each: a refinement stage of 256 lens cells at two ranges
def _norm_tables(cell: LensCell, span: float) -> bytes:
    """The N(ρ) tables slice_prepare.frag reads for ``cell`` (its fine one, and one over [0, ``span``]),
    made once per cell and range: the whole aperture's cell is one object per aperture
    (Aperture.whole) and refinement's cells one per stage (progressive.lens_cells)."""
    return np.concatenate([cell.norms(NORM_FINE), cell.norms(span)]).tobytes()


@functools.lru_cache(maxsize=1024)  # as LensCell.taps: a frame's layers, and a refinement stage's cells
def _tap_uniform(cell: LensCell, radius: float) -> tuple[bytes, bytes, int, int]:
    """The gather's u_tap array for sources of |ρ| ≤ ``radius`` level px (LensCell.taps), its
    u_prefix table, the number of taps and their reach (level px).

    u_prefix[k] is how many of the taps (nearest first) a pixel needs whose sources within reach
    all have |ρ| < (k + 1)/PREFIX_STEPS: one past the last tap of onset (LensCell.tap_onsets) up to
    that, so that every tap such a source gives weight is among them (the last entry: all)."""
    taps = cell.taps(radius)
    if len(taps) > MAX_TAPS:
        raise DofviewError(f"a kernel of {len(taps)} taps exceeds the sliced mode's {MAX_TAPS}")
    data = np.zeros((MAX_TAPS, 2), np.float32)
    data[:len(taps)] = taps
    bounds = (np.arange(MAX_PREFIX) + 1.0) / PREFIX_STEPS
    needed = cell.tap_onsets(radius)[None, :] <= bounds[:, None]
    prefix = np.max(np.where(needed, np.arange(1, len(taps) + 1), 0), axis=1).astype(np.int32)
    prefix[-1] = len(taps)
    return data.tobytes(), prefix.tobytes(), len(taps), int(np.abs(taps).max())


def _setup_spans(layers: list[Layer]) -> list[tuple[int, int]]:
    """Per layer, (first, end) of the front-to-back order of the run of consecutive layers drawn
    with its lens (the pinhole, or the lens for the huge-CoC layers): what one prepare_splats
    serves."""
    spans: list[tuple[int, int]] = []
    for index, layer in enumerate(layers):
        if index and layers[index - 1].lensed == layer.lensed:
            spans.append(spans[-1])
            continue
        end = index
        while end + 1 < len(layers) and layers[end + 1].lensed == layer.lensed:
            end += 1
        spans.append((layer.first, layers[end].end))
    return spans


def _intersect(a: Box, b: Box) -> Box:
    return max(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), min(a[3], b[3])


def _union(a: Box | None, b: Box) -> Box:
    return b if a is None else (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))


@dataclass
class _Level:
    """The targets of one level 1/scale: the prepared layer (colour / N, and (r, visible / N)) and,
    for a reduced level, the layer averaged down to it (colour, depth sums with the visible
    coverage: slice_reduce.frag) and the accumulators of a run ("over" colour, visible sum)."""

    scale: int
    a: moderngl.Texture
    b: moderngl.Texture
    prepared: moderngl.Framebuffer
    colour: moderngl.Texture | None
    depth: moderngl.Texture | None
    reduced: moderngl.Framebuffer | None
    run: moderngl.Framebuffer | None
    occupied: moderngl.Texture  # per 8 × 8 tile of the level: the largest |ρ| within the gather's reach (−1: none)
    dirty: Box | None = None  # what the last prepare wrote (level pixels)

    def textures(self) -> list[moderngl.Texture]:
        own = [self.a, self.b, self.occupied] + ([self.colour, self.depth] if self.colour is not None else [])
        return own + list(self.run.color_attachments if self.run is not None else ())

    def release(self) -> None:
        for obj in (self.prepared, *(f for f in (self.reduced, self.run) if f is not None), *self.textures()):
            obj.release()


class SlicedDof:
    """The sliced mode of one :class:`~dofview.rendering.base.Renderer` (made by its first sliced
    draw; its targets follow the frame size)."""

    def __init__(self, renderer) -> None:
        self.r = renderer
        ctx = renderer.ctx
        self.ctx = ctx

        def program(frag: str, vert: str = "fullscreen.vert") -> tuple[moderngl.Program, moderngl.VertexArray]:
            prog = ctx.program(vertex_shader=load_shader(vert),
                               fragment_shader=load_shader(frag, {"MAX_TAPS": MAX_TAPS, "MAX_PLANES": MAX_PLANES,
                                                                  "NORM_SAMPLES": NORM_SAMPLES, "NORM_FINE": repr(NORM_FINE),
                                                                  "MAX_PREFIX": MAX_PREFIX,
                                                                  "PREFIX_STEPS": repr(float(PREFIX_STEPS))}))
            return prog, ctx.vertex_array(prog, [])

        tile = {"TILE": TILE, "MARKS_BINDING": MARKS_BINDING}
        self._list = compute_shader(ctx, "slice_tiles.comp", tile)
        self._visible = compute_shader(ctx, "slice_visible.comp", tile)
        # at full resolution, the visible pass also prepares the layer and empties the slice target
        self._visible_prepare = compute_shader(ctx, "slice_visible.comp", {
            **tile, "PREPARE": 1, "NORM_SAMPLES": NORM_SAMPLES, "NORM_FINE": repr(NORM_FINE)})
        self._accept = compute_shader(ctx, "sprite_accept.comp")
        self._occupancy = compute_shader(ctx, "slice_occupancy.comp", tile)
        self._reduce = program("slice_reduce.frag")
        # the passes at full resolution, drawn over the tiles a layer's blend marked
        self._reduce_tiles = program("slice_reduce.frag", "slice_tiles.vert")
        self._empty_tiles = program("slice_empty.frag", "slice_tiles.vert")
        self._upsample_tiles = program("slice_upsample.frag", "slice_tiles.vert")
        self._tile_commands = ctx.buffer(reserve=32)  # slice_tiles.comp's indirect draw and dispatch
        self._linear = ctx.sampler(filter=(moderngl.LINEAR, moderngl.LINEAR), repeat_x=False, repeat_y=False)
        self._prepare = program("slice_prepare.frag")
        self._gather = program("slice_gather.frag")
        defines = {"MAX_TAPS": MAX_TAPS, "MAX_PLANES": MAX_PLANES, **tile}
        sprite = ctx.program(vertex_shader=load_shader("slice_sprite.vert", defines),
                             fragment_shader=load_shader("slice_sprite.frag", defines))
        self._sprite = sprite, ctx.vertex_array(sprite, [])
        self._sprite_list = ctx.buffer(reserve=SPRITE_HEADER)  # slice_prepare.frag's Sprites: sized per frame
        self._sprite_draw = ctx.buffer(reserve=16)  # a layer's indirect draw of its sprites
        self._again = ctx.buffer(reserve=16)  # the indirect draw of a refused layer's prepare without highlights
        self._resolve = program("slice_resolve.frag")
        self._size: tuple[int, int] | None = None
        self.guard = 0
        """The guard band of the last draw, pixels beyond the frame on every side (slices.guard_band)."""
        self._key: tuple[int, int, int] | None = None  # size and the renderer's colour target
        self._levels: dict[int, _Level] = {}
        self._norms = self._texture((NORM_SAMPLES, 4), 1)  # the kernel's N(ρ) tables (LensCell.norms)
        self._norms_for: tuple[LensCell, float] | None = None  # (cell, range) they were made for
        self._taps_set: bytes | None = None  # the gather's taps as last written (_tap_uniform)
        self._written: dict[int, dict[str, object]] = {}  # per program, the uniforms _pass last set
        self._planner: GpuLayerPlan | None = None  # made by the first draw with an aperture
        self.layers: list[Layer] = []
        """The layers of the last draw (Renderer.sliced_layers)."""
        self.pinhole = False
        """Whether the last draw's plan was the pinhole's (FramePlan.pinhole: nothing blurred)."""
        self.capture = None
        """Set by the deep image (rendering/deep_sliced.py, a SliceCapture): told where each layer
        was composited, to read it back; the draw itself is unchanged."""
        self.timer: Callable[[str], None] | None = None
        """Set by the pass profile (``python -m dofview.bench.sliced_study passes``): called with
        the kind of the GPU work issued since its last call ("blend", "gather", …), to wait for it
        and time it; the draw is otherwise unchanged."""

    # ---- targets -------------------------------------------------------------------------------
    def _texture(self, size: tuple[int, int], components: int = 4) -> moderngl.Texture:
        tex = self.ctx.texture(size, components, dtype="f4")
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        return tex

    def _targets(self, width: int, height: int) -> None:
        """Targets the size of the guarded image, and the framebuffer that writes the renderer's
        targets (made again with them)."""
        key = (width, height, self.r.colour_tex.glo)
        if self._key == key:
            return
        self._release_targets()
        size = (width, height)
        self.slice_colour, self.slice_depth, self.over, self.visible, self.acc_depth = (
            self._texture(size) for _ in range(5))
        self.sprite_colour, self.sprite_visible = self._texture(size), self._texture(size, 1)
        fb = self.ctx.framebuffer
        self.slice_fbo = fb(color_attachments=[self.slice_colour, self.slice_depth])
        self.frame_fbo = fb(color_attachments=[self.over, self.visible])
        self.acc_fbo = fb(color_attachments=[self.acc_depth])
        self.sprite_fbo = fb(color_attachments=[self.sprite_colour, self.sprite_visible])
        self.output_fbo = fb(color_attachments=[self.r.colour_tex, self.r.depth_tex])
        self.slice_fbo.clear(0.0, 0.0, 0.0, 0.0)  # then kept empty: each layer's prepare clears what it reads
        columns, rows = -(-width // TILE), -(-height // TILE)
        self._marks = TileMarks(self.ctx.buffer(data=np.zeros(columns * rows, np.uint32).tobytes()), TILE, columns)
        self._tile_list = self.ctx.buffer(reserve=8 * columns * rows)  # slice_tiles.comp's tiles
        self._tile_runs = self.ctx.buffer(reserve=16 * columns * rows)  # and runs of them
        # where a run of reduced layers holds light (slice_occupancy.comp) or sprites (slice_sprite.vert)
        self._run_marks = TileMarks(self.ctx.buffer(data=np.zeros(columns * rows, np.uint32).tobytes()), TILE, columns)
        self.sprite_fbo.clear(0.0, 0.0, 0.0, 0.0)  # likewise: each run's upsample clears what it read
        self._size, self._key = size, key

    def _level(self, scale: int) -> _Level:
        """The targets at 1/``scale`` resolution, made (cleared) on first use."""
        if scale not in self._levels:
            w, h = self._size
            size = (-(-w // scale), -(-h // scale))
            a, b = self._texture(size), self._texture(size, 2)
            colour = depth = reduced = run = None
            if scale > 1:
                colour, depth = self._texture(size), self._texture(size)
                reduced = self.ctx.framebuffer(color_attachments=[colour, depth])
                run = self.ctx.framebuffer(color_attachments=[self._texture(size), self._texture(size)])
            prepared = self.ctx.framebuffer(color_attachments=[a, b])
            prepared.clear(0.0, 0.0, 0.0, 0.0)
            occupied = self._texture((-(-size[0] // 8), -(-size[1] // 8)), 1)
            self._levels[scale] = _Level(scale, a, b, prepared, colour, depth, reduced, run, occupied)
        return self._levels[scale]

    @property
    def gpu_bytes(self) -> int:
        """Bytes of the slice targets as now allocated."""
        if self._size is None:
            return 0
        w, h = self._size
        own = (5 * 16 + 16 + 4) * w * h + self._sprite_list.size + self._sprite_draw.size + self._again.size
        own += (2 * self._marks.buffer.size + self._tile_list.size + self._tile_runs.size
                + self._tile_commands.size)
        for level in self._levels.values():
            own += sum(t.width * t.height * t.components * 4 for t in level.textures())
        return own

    @property
    def plan_bytes(self) -> int:
        """Bytes of the GPU plan's buffers (per Gaussian: layer_plan.GpuLayerPlan)."""
        return self._planner.gpu_bytes if self._planner is not None else 0

    # ---- one frame -----------------------------------------------------------------------------
    def draw(self, camera: Camera, lens: Lens, settings: RenderSettings, count: bool,
             cell: LensCell | None = None) -> None:
        """The sliced image of the renderer's scene in its current order into its targets, blurred
        by the kernel of ``cell`` (None: the whole aperture of ``settings``)."""
        r = self.r
        rule = r.slice_rule or rule_for(settings.blades)
        cell = cell or Aperture(settings.blades, math.radians(settings.blade_rotation)).whole()
        if lens.aperture == 0.0:  # nothing to plan: no Gaussian is looked at
            plan = pinhole_plan(r.scene.count, camera.width, camera.height)
        else:
            if self._planner is None:
                self._planner = GpuLayerPlan(r)
            size = math.sqrt(cell.share)
            plan = frame_plan(self._planner.measure(camera, lens, settings, rule, size), camera, rule, size)
            self._lap("plan")
        self.layers, self.guard, self.pinhole = plan.layers, plan.guard, plan.pinhole
        if plan.pinhole:
            # nothing to blur (A = 0): the layer is the pinhole frame, drawn straight into the
            # renderer's targets instead of through a layer target, gather and resolve at full size
            r.splat_scene(camera, Lens(lens.focus, 0.0), replace(settings, dof="splat"), count)
            return
        self._set_cell(cell, max((layer.radius / layer.scale for layer in self.layers if not layer.lensed), default=0.0))
        camera = camera.guarded(self.guard)  # every pass below works in the guarded image
        w, h = camera.width, camera.height
        self._targets(w, h)
        # the frame inside the guarded image (GL pixels): only there are the blurred layers
        # composited; the band is a source of light for the gathers, not a part of the image
        frame = (self.guard, self.guard, w - self.guard, h - self.guard)
        self._clear(self.frame_fbo, frame)
        self.acc_fbo.clear(0.0, 0.0, 0.0, 0.0)  # the pinhole's depth sums, accumulated layer by layer
        self._lap("clear")
        cap = sprite_cap(rule, w - 2 * self.guard, h - 2 * self.guard)
        sprite_frame = (max(w, h) - 2 * self.guard) / math.sqrt(cell.share)  # in px of the kernel's blur
        self._sprites_for(cap)
        pinhole = (Lens(lens.focus, 0.0), replace(settings, dof="splat"), count)
        # the huge-CoC front and back layers, drawn blurred, see the lens cell's share of the aperture
        lensed = (Lens(lens.focus, lens.aperture * math.sqrt(cell.share)), replace(settings, dof="splat"), count)
        spans = _setup_spans(plan.layers)
        prepared = None
        run: list = []  # [level, box (full-resolution pixels)] of the run being composited
        for index, (layer, box, sides) in enumerate(zip(plan.layers, plan.windows, plan.edges)):
            level = self._level(layer.scale)
            if run and run[0] is not level:
                self._end_run(run)
            if box[2] <= box[0] or box[3] <= box[1]:
                continue  # nothing of it within its reach of the frame: it adds nothing (but ends a run)
            setup = lensed if layer.lensed else pinhole
            # a run's own span: the front and back lensed runs share a setup, and the pinhole run
            # between them may have drawn nothing (every window empty), which left the front's span
            if prepared != (setup, spans[index]):
                r.prepare_splats(camera, *setup, span=spans[index])
                prepared = (setup, spans[index])
                self._lap("prepare splats")
            s = layer.scale  # GL rows, from the bottom, widened to whole blocks of the layer's level
            gl_box = (box[0] // s * s, (h - box[3]) // s * s, min(-(-box[2] // s) * s, w), min(-(-(h - box[1]) // s) * s, h))
            r.splat_range(layer.first, layer.end, self.slice_fbo, box, self._marks)
            self._lap("blend")
            reach = self._write_taps(cell, layer.radius / layer.scale)
            sprites = has_sprites(layer, rule, cap, sprite_frame)  # a reduced layer's highlights
            blocks = self._prepare_layer(level, gl_box, layer, lens, rule, cap if sprites else 0)
            out = _intersect(self._grow(blocks, reach, level), self._grow(self._blocks(frame, s), 1, level))
            if level.run is None:
                self._gather_layer(level, self.frame_fbo, out, reach, sides, frame)
            else:
                fresh = not run
                if fresh:
                    level.run.clear(0.0, 0.0, 0.0, 0.0)
                    run.extend([level, None])
                    self._lap("clear")
                if sprites:  # each reaches its own kernel's extent beyond the layer's blocks
                    spread = math.ceil(layer.radius * cell.reach + 1.5)
                    lit = _intersect((blocks[0] * s - spread, blocks[1] * s - spread, blocks[2] * s + spread,
                                      blocks[3] * s + spread), frame)
                    if lit[2] > lit[0] and lit[3] > lit[1]:
                        self._draw_sprites(lit)
                        run[1] = _union(run[1], lit)
                self._gather_layer(level, level.run, out, reach, sides, frame)
                # the run's reach at full resolution, a block more for the bilinear upsampling
                run[1] = _union(run[1], _intersect(((out[0] - 1) * s, (out[1] - 1) * s, (out[2] + 1) * s,
                                                     (out[3] + 1) * s), frame))
                if sprites:
                    # the layer is a run of its own: the layers behind it must be hidden by its
                    # sprites' coverage too, which only the frame's accumulators hold
                    reach_box = run[1]
                    self._end_run(run)
            if self.capture is not None:
                if level.run is None:
                    self.capture.layer(index, self.frame_fbo, out, 1, False)
                elif sprites:  # composited with its sprites into the frame, within the run's reach
                    self.capture.layer(index, self.frame_fbo, reach_box, 1, False)
                else:
                    self.capture.layer(index, level.run, out, s, fresh)
        if run:
            self._end_run(run)
        prog, vao = self._resolve
        g = self.guard
        self._pass(prog, vao, self.output_fbo, {"u_over": 0, "u_visible": 1, "u_depth": 2, "u_guard": g},
                   [self.over, self.visible, self.acc_depth], (0, 0, w - 2 * g, h - 2 * g))
        self._lap("resolve")

    def _lap(self, kind: str) -> None:
        if self.timer is not None:
            self.timer(kind)

    @staticmethod
    def _blocks(box: Box, scale: int) -> Box:
        """The blocks of a 1/``scale`` level that cover ``box`` (full-resolution GL pixels)."""
        return box[0] // scale, box[1] // scale, -(-box[2] // scale), -(-box[3] // scale)

    def _grow(self, box: Box, n: int, level: _Level) -> Box:
        """``box`` (level pixels) and ``n`` pixels around it, clipped to the level."""
        lw, lh = level.a.size
        return max(box[0] - n, 0), max(box[1] - n, 0), min(box[2] + n, lw), min(box[3] + n, lh)

    def _write_taps(self, cell: LensCell, radius: float) -> int:
        """Set the gather's taps (slice_kernel.glsl: two offsets a vector) for sources of |ρ| ≤
        ``radius`` level px of ``cell``'s kernel, unless they are set already; returns their reach
        (level px)."""
        data, prefix, count, reach = _tap_uniform(cell, radius)
        if self._taps_set is not data:
            prog = self._gather[0]
            prog["u_tap"].write(data)
            prog["u_prefix"].write(prefix)
            prog["u_taps"].value = count
            prog["u_tap_reach"].value = reach
            self._taps_set = data
        return reach

    def _set_cell(self, cell: LensCell, radius: float) -> None:
        """Set the kernel of the gather and of the sprites (slice_kernel.glsl), and the tables of its
        N(ρ) that the prepare reads (LensCell.norms) for |ρ| ≤ ``radius`` (level px: the largest
        blur of any layer at its level), uploaded again only when the cell changes or the radius
        passes a quarter octave and made once per cell and range (:func:`_norm_tables`)."""
        point, planes = cell.gl()
        if len(planes) > MAX_PLANES:
            raise DofviewError(f"a lens cell of {len(planes)} edges exceeds the sliced mode's {MAX_PLANES}")
        data = np.zeros((MAX_PLANES, 4), np.float32)
        data[:len(planes), :3] = planes
        for prog in (self._gather[0], self._sprite[0]):
            prog["u_point"].value = tuple(float(v) for v in point)
            prog["u_disk"].value = cell.disk
            prog["u_planes"].value = len(planes)
            prog["u_plane"].write(data.tobytes())
        self._sprite[0]["u_reach"].value = cell.reach
        span = max(NORM_FINE, 2.0 ** (math.ceil(4.0 * math.log2(max(radius, NORM_FINE))) / 4.0))
        if self._norms_for != (cell, span):
            self._norms.write(_norm_tables(cell, span))
            self._norms_for = (cell, span)

    def _prepare_layer(self, level: _Level, box: Box, layer: Layer, lens: Lens, rule: SliceRule,
                       sprites: int) -> Box:
        """The layer in the slice target, within ``box`` (GL pixels, whole blocks of the level),
        made ready for its gather at ``level`` (slices.prepare): the tiles its blend marked listed
        (slice_tiles.comp), slice_visible.comp over them, then slice_reduce.frag down to the level
        and slice_prepare.frag, after clearing what the last layer prepared there wrote (the gather
        reads around its blocks, where the level must be empty); the passes at full resolution
        run in the listed tiles only, and the slice target is emptied there once read. At full
        resolution slice_visible.comp prepares the layer and empties the slice target itself (one
        pass reading the layer once, instead of three).
        ``sprites``: the frame's cap of sprites, for which the prepare also takes the layer's
        highlights out into the sprite list, and their count into :attr:`_sprite_draw` (0: no
        highlights): all of them if they fit in what is left of the cap, else none
        (sprite_accept.comp, then the prepare again without highlights, drawn indirectly only
        then; slices.highlights).
        Returns the level's blocks."""
        s = layer.scale
        self._list_tiles(box, self._marks)
        self._lap("list tiles")
        self._clear(level.prepared, level.dirty)
        self._lap("clear")
        uniforms = {"u_norm_range": self._norms_for[1], "u_scale": s,
                    "u_blur": not layer.lensed, "u_aperture": lens.aperture,
                    "u_inv_focus": float32_uniform(lens.inv_focus), "u_shrink": 4.0 * rule.spread * (s * s - 1),
                    "u_rmax": layer.radius / s}
        self._norms.bind_to_image(7, read=True, write=False)
        self.acc_depth.bind_to_image(0, read=True, write=True)
        self.slice_colour.bind_to_image(1, read=True, write=True)
        self.slice_depth.bind_to_image(2, read=True, write=True)
        if s == 1:  # one pass: visible, prepared into the level and the slice target emptied
            visible = self._visible_prepare
            for name, value in {"u_box": box, **uniforms}.items():
                visible[name].value = value
            level.a.bind_to_image(3, read=False, write=True)
            level.b.bind_to_image(5, read=False, write=True)
            visible.run_indirect(self._tile_commands, offset=16)
            self.ctx.memory_barrier()
            self._lap("visible + prepare")
            level.dirty = box
            return box
        self._visible["u_box"].value = box
        self._visible.run_indirect(self._tile_commands, offset=16)
        self.ctx.memory_barrier()
        self._lap("visible")
        colour, depth, region = self._reduce_layer(box, s)
        self._lap("reduce")
        level.dirty = region
        prog, vao = self._prepare
        uniforms.update({"u_sprites": sprites > 0, "u_cap": max(sprites, 0)})
        colour.bind_to_image(3, read=True, write=False)
        depth.bind_to_image(4, read=True, write=False)
        if sprites > 0:  # the highlights' uniforms, and this layer's draw of none so far
            self._sprite_draw.write(_NO_SPRITES)
            self._sprite_list.bind_to_storage_buffer(0)
            self._sprite_draw.bind_to_storage_buffer(1)
            self.slice_colour.bind_to_image(5, read=True, write=False)
            self.slice_depth.bind_to_image(6, read=True, write=False)
            uniforms.update({"u_region": region,
                             "u_bright": rule.bright, "u_excess": rule.excess, "u_dim": rule.dim})
        self._pass(prog, vao, level.prepared, uniforms, [], region)
        if sprites > 0:
            # drawn all or none (the GPU's order must not choose which): a layer whose highlights
            # do not fit in what is left of the cap is prepared again without them
            self.ctx.memory_barrier()
            self._again.write(_NOT_AGAIN)
            self._again.bind_to_storage_buffer(2)
            self._accept["u_cap"].value = sprites
            self._accept.run(1)
            self.ctx.memory_barrier()
            self._pass(prog, vao, level.prepared, {**uniforms, "u_sprites": False}, [], region, again=True)
        self._lap("prepare")
        # (emptied only now: the highlights are taken from the full-resolution layer)
        self._pass(*self._empty_tiles, self.slice_fbo, {}, [], box, tiles=1)
        self._lap("empty")
        return region

    def _list_tiles(self, box: Box, marks: TileMarks) -> None:
        """List the tiles of ``box`` (GL pixels) that ``marks`` holds (a layer's blend's, or a
        run's), clearing their marks (slice_tiles.comp), with the indirect draw and dispatch over
        them in :attr:`_tile_commands`."""
        self.ctx.memory_barrier()  # the marks the blend, the gathers or the sprites stored
        self._tile_commands.write(_NO_TILES)
        tiles = (box[0] // TILE, box[1] // TILE, -(-box[2] // TILE), -(-box[3] // TILE))
        marks.buffer.bind_to_storage_buffer(MARKS_BINDING)
        self._tile_list.bind_to_storage_buffer(4)
        self._tile_runs.bind_to_storage_buffer(5)
        self._tile_commands.bind_to_storage_buffer(6)
        self._list["u_tiles"].value = tiles
        self._list["u_columns"].value = marks.columns
        self._list.run(-(-(tiles[3] - tiles[1]) // 64))
        self.ctx.memory_barrier()

    def _reduce_layer(self, box: Box, scale: int) -> tuple[moderngl.Texture, moderngl.Texture, Box]:
        """The slice target within ``box`` (GL pixels) averaged down to the level 1/``scale``
        (slice_reduce.frag: 4 × 4 a pass while that does not pass the level, else 2 × 2), the
        first pass in the listed tiles only (:meth:`_list_tiles`: elsewhere the level is cleared);
        returns the level's colour and depth sums (the slice target's at scale 1) and the blocks
        written."""
        colour, depth, region = self.slice_colour, self.slice_depth, box
        step = 1
        while step < scale:
            factor = 4 if 4 * step <= scale else 2
            dest = self._level(step * factor)
            region = self._blocks(region, factor)
            if step == 1:
                self._clear(dest.reduced, region)
            prog, vao = self._reduce_tiles if step == 1 else self._reduce
            self._linear.use(0)
            self._linear.use(1)
            self._pass(prog, vao, dest.reduced, {"u_colour": 0, "u_depth": 1, "u_factor": factor}, [colour, depth],
                       region, tiles=factor if step == 1 else 0)
            step *= factor
            self._linear.clear(0)
            self._linear.clear(1)
            colour, depth = dest.colour, dest.depth
        return colour, depth, region

    def _sprites_for(self, cap: int) -> None:
        """A sprite list for ``cap`` sprites, none of them taken yet this frame."""
        size = SPRITE_HEADER + max(cap, 1) * SPRITE_BYTES
        if self._sprite_list.size < size:
            self._sprite_list.orphan(size)
        self._sprite_list.write(np.zeros(4, np.uint32).tobytes())

    def _draw_sprites(self, box: Box) -> None:
        """The sprites the layer's prepare listed (slice_sprite.vert/.frag), drawn indirectly with
        the count it wrote, within ``box`` (full-resolution GL pixels: their reach in the frame),
        added into the sprite targets, marking their tiles in :attr:`_run_marks`."""
        self.ctx.memory_barrier()  # the prepare's list and count, for the vertex stage and the draw
        prog, vao = self._sprite
        self._sprite_list.bind_to_storage_buffer(0)
        prog["u_size"].value = tuple(float(v) for v in self._size)
        prog["u_columns"].value = self._run_marks.columns
        prog["u_box"].value = box
        self._run_marks.buffer.bind_to_storage_buffer(MARKS_BINDING)
        ctx = self.ctx
        self.sprite_fbo.use()
        ctx.viewport = (0, 0, *self._size)
        ctx.scissor = (box[0], box[1], box[2] - box[0], box[3] - box[1])
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.ONE, moderngl.ONE
        ctx.blend_equation = moderngl.FUNC_ADD
        vao.render_indirect(self._sprite_draw, moderngl.TRIANGLE_STRIP, count=1)
        ctx.disable(moderngl.BLEND)
        ctx.scissor = None
        self._lap("sprites")

    def _gather_layer(self, level: _Level, target: moderngl.Framebuffer, out: Box, reach: int, edges: Edges,
                      frame: Box) -> None:
        """slice_gather.frag over ``out`` (level pixels), blended behind what ``target`` holds,
        repeating the level's edge beyond the sides ``edges`` names, after slice_occupancy.comp has
        found for each of its tiles the largest |ρ| of the light within ``reach`` texels (none: the
        tile is left at once; else only the taps such light can reach are visited); into a run's
        accumulators, it marks where the run's upsampling will read that light (full-resolution
        tiles within ``frame``, GL pixels, and ``out`` a texel wider: :attr:`_run_marks`)."""
        if out[2] <= out[0] or out[3] <= out[1]:
            return
        occ = self._occupancy
        s = level.scale
        occ["u_mark"].value = target is level.run
        if target is level.run:
            occ["u_scale"].value = s
            occ["u_columns"].value = self._run_marks.columns
            occ["u_frame"].value = _intersect(((out[0] - 1) * s, (out[1] - 1) * s, (out[2] + 1) * s, (out[3] + 1) * s),
                                              frame)
            self._run_marks.buffer.bind_to_storage_buffer(MARKS_BINDING)
        tiles = (out[0] // 8, out[1] // 8, -(-out[2] // 8), -(-out[3] // 8))
        level.occupied.bind_to_image(0, read=False, write=True)
        level.a.bind_to_image(1, read=True, write=False)  # (and for the gather)
        level.b.bind_to_image(2, read=True, write=False)
        occ["u_tiles"].value = tiles
        occ["u_reach"].value = reach
        occ.run(-(-(tiles[2] - tiles[0]) // 8), -(-(tiles[3] - tiles[1]) // 8))
        self.ctx.memory_barrier()
        self._lap("occupancy")
        prog, vao = self._gather
        prog["u_edge"].value = edges
        self._pass(prog, vao, target, {"u_occupied": 0}, [level.occupied], out, blend=True)
        self._lap("gather")

    def _end_run(self, run: list) -> None:
        """Upsample the run's accumulators into the frame's, behind what they hold, in the tiles
        its gathers and sprites marked (elsewhere it holds nothing), and empty the sprite targets
        there."""
        level, box = run
        if box is not None:
            self._list_tiles(box, self._run_marks)
            self._lap("list tiles")
            prog, vao = self._upsample_tiles
            self._linear.use(0)  # the run's accumulators, filtered bilinearly
            self._linear.use(1)
            self._pass(prog, vao, self.frame_fbo,
                       {"u_over": 0, "u_visible": 1, "u_sprites": 2, "u_sprite_visible": 3, "u_scale": level.scale},
                       [*level.run.color_attachments, self.sprite_colour, self.sprite_visible], box, blend=True,
                       tiles=1)
            self._linear.clear(0)
            self._linear.clear(1)
            self._lap("upsample")
            self._pass(*self._empty_tiles, self.sprite_fbo, {}, [], box, tiles=1)
            self._lap("empty")
        run.clear()

    def _clear(self, fbo: moderngl.Framebuffer, box: Box | None) -> None:
        if box is not None and box[2] > box[0] and box[3] > box[1]:
            fbo.clear(0.0, 0.0, 0.0, 0.0, viewport=(box[0], box[1], box[2] - box[0], box[3] - box[1]))

    def _pass(self, prog: moderngl.Program, vao: moderngl.VertexArray, fbo: moderngl.Framebuffer,
              uniforms: dict[str, object], textures: list[moderngl.Texture], box: Box, blend: bool = False,
              again: bool = False, tiles: int = 0) -> None:
        """One full-screen pass of ``prog`` into ``fbo`` reading ``textures`` at units 0, 1, …,
        limited to ``box`` (target pixels, GL rows); ``blend``: front to back behind what ``fbo``
        holds (ONE_MINUS_DST_ALPHA, ONE); ``again``: drawn only if sprite_accept.comp refused the
        layer's highlights (indirectly, from the count it wrote: no read-back); ``tiles``: only
        in the listed tiles (:meth:`_list_tiles`; ``prog`` linked with slice_tiles.vert), ``fbo``
        being at 1/``tiles`` of full resolution."""
        if box[2] <= box[0] or box[3] <= box[1]:
            return
        if tiles:
            uniforms = {**uniforms, "u_tile": TILE / tiles, "u_target": tuple(float(v) for v in fbo.size)}
            self._tile_runs.bind_to_storage_buffer(5)
        for unit, tex in enumerate(textures):
            tex.use(unit)
        written = self._written.setdefault(prog.glo, {})
        for name, value in uniforms.items():
            if written.get(name, _UNSET) != value:  # most are the frame's, or the last layer's
                prog[name].value = value
                written[name] = value
        ctx = self.ctx
        fbo.use()
        ctx.viewport = (0, 0, *fbo.size)
        ctx.scissor = (box[0], box[1], box[2] - box[0], box[3] - box[1])
        if blend:
            ctx.enable(moderngl.BLEND)
            ctx.blend_func = moderngl.ONE_MINUS_DST_ALPHA, moderngl.ONE
            ctx.blend_equation = moderngl.FUNC_ADD
        if again:
            vao.render_indirect(self._again, moderngl.TRIANGLES, count=1)
        elif tiles:
            vao.render_indirect(self._tile_commands, moderngl.TRIANGLE_STRIP, count=1)
        else:
            vao.render(moderngl.TRIANGLES, vertices=3)
        if blend:
            ctx.disable(moderngl.BLEND)
        ctx.scissor = None

    def _release_targets(self) -> None:
        if self._size is not None:
            for obj in (self.slice_fbo, self.frame_fbo, self.acc_fbo, self.sprite_fbo, self.output_fbo,
                        self.slice_colour, self.slice_depth, self.over, self.visible, self.acc_depth,
                        self.sprite_colour, self.sprite_visible, self._marks.buffer, self._tile_list,
                        self._tile_runs, self._run_marks.buffer):
                obj.release()
        for level in self._levels.values():
            level.release()
        self._levels = {}
        self._size = self._key = None

    def release(self) -> None:
        """Free the slice targets and programs."""
        self._release_targets()
        for prog, vao in (self._reduce, self._reduce_tiles, self._prepare, self._empty_tiles,
                          self._gather, self._sprite, self._upsample_tiles, self._resolve):
            vao.release()
            prog.release()
        self._sprite_list.release()
        self._sprite_draw.release()
        self._again.release()
        self._visible.release()
        self._visible_prepare.release()
        self._list.release()
        self._tile_commands.release()
        self._occupancy.release()
        self._linear.release()
        self._norms.release()
        if self._planner is not None:
            self._planner.release()
