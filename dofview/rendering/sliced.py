"""Sliced depth of field on the GPU (``RenderSettings.dof == "sliced"``), the GL twin of slices.py.

The backend's draw order, nearest first, is cut into contiguous ranges by signed CoC
c = ½·A·(1/z − 1/d_f) px with slices.py's rule (:data:`SLICE_RULE`). Front to back, each range is
blended by the backend as a pinhole (τ = 0, no CoC enlargement: :meth:`Renderer._splat_range`)
into one reused slice target, gathered with the aperture kernel of its radius
(slices.aperture_kernel; at 1/2ᵏ resolution above :func:`full_radius_limit`, with the replicate
guard band), and added to two accumulators in the space the scene blends in: "over" (what a
blurred foreground edge hid shows through) and the sum of its blurred *visible* parts (weighted by
the pinhole transmittance in front, so a surface cut by slice boundaries stays whole); where the
"over" coverage falls short of the visible sum's, the latter makes up the deficit (slices.sliced_image
mode "hybrid", :data:`COMPOSITE`).
The result goes into the renderer's own targets, the depth target holding the pinhole's depth
sums, so EXR, depth, the display pass and click-to-focus serve it like any draw. The splats beyond
``SLICE_RULE.huge`` px of CoC (near the camera indoors) form a front and a back layer drawn by the
per-splat method with the lens and the frame's settings. At A = 0 there is one slice and no blur:
the pinhole render.

Only the pixels a slice's Gaussians can reach (:func:`screen_boxes`) and its blur radius around
them are blurred and composited. GPU memory: seven camera-sized RGBA32F targets (slice colour, slice
depth sums, blurred slice, the two accumulators, share, sum), 112 B per pixel, plus per reduced level
s two targets of 32/s² B per pixel (≤ 10.7 B in all): ≤ 117 MiB per megapixel besides the renderer's
own targets and the grey core storage.

Neighbour sharing, as slices.py's default (:func:`~dofview.rendering.slices.share_weights`): the
layers are the depth ranges between consecutive slice centres, each splat's share t of the farther
centre linear in its CoC. A shared layer is blended a second time with t as a grey colour (the
scene's storage swapped for :class:`GreyCore`'s) into the share target; each pixel's content is
split by τ = share / coverage between the two centres' blurs, summed in the sum target before it
is composited as one layer. So the blur follows each splat's CoC instead of stepping at slice
edges, and a slanted floor is seamless. Its storage: a second copy of the core storage on the GPU
and the host (32 B per Gaussian packed, 56 B in float32), and a zeroed SH-rest buffer as large as
the scene's; per frame the grey levels are written (the core's size) and, on the compute backend,
the whole scene is preprocessed twice more per shared layer (grey, then the colours again).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import moderngl
import numpy as np

from dofview.camera import Camera
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering.depth_order import camera_depths
from dofview.rendering.gl import load_shader
from dofview.rendering.packing import full_core, pack_core
from dofview.rendering.slices import SliceRule, aperture_kernel, assign_slices, share_weights, signed_coc

SLICE_RULE = SliceRule()
"""The slicing of both the GL path and its CPU reference (slices.py's default rule)."""
COMPOSITE = "hybrid"
"""slices.sliced_image's composite the GL path computes: the "over" composite, topped up where its
coverage falls short of the sum of blurred visible parts (seamless where a surface crosses slices)."""
MAX_FULL_RADIUS = 4.0
"""Blur radius (px) above which a slice is blurred at the 1/2ᵏ resolution that brings it below: against
the thin lens on the five real scenes 4 px scores as 8 px does (−0.08 to +0.5 dB) at a fraction of
the gather's cost, 2 px loses up to 2.9 dB (docs/BENCHMARKS.md, "Sliced depth of field on the GPU")."""
BLADED_FULL_RADIUS = 8.0
"""The same limit for a bladed aperture: a polygon gathered at ≤ 4 px comes out a round blob (a
20 px bokeh at 1/8 resolution), at ≤ 8 px its corners show."""


def full_radius_limit(blades: int) -> float:
    """The blur radius px above which slices blur at reduced resolution, for ``blades`` (0: a disk)."""
    return BLADED_FULL_RADIUS if blades else MAX_FULL_RADIUS


def blur_scale(radius: float, limit: float = MAX_FULL_RADIUS) -> int:
    """The resolution reduction (1, 2, 4, …) that brings a blur of ``radius`` px to ≤ ``limit`` px."""
    return 1 if radius <= limit else 1 << math.ceil(math.log2(radius / limit))


@dataclass(frozen=True)
class Layer:
    """One range [first, end) of the front-to-back order: a slice blurred by ``radius`` px, or
    (``lensed``) a huge-CoC layer drawn with the lens by the per-splat method and not blurred.
    ``back_radius``: a shared layer (between two slice centres), whose share τ of each pixel is
    blurred by this radius px (the farther centre's) and the rest by ``radius``; None: not shared."""

    first: int
    end: int
    radius: float
    lensed: bool
    back_radius: float | None = None


def plan_layers(depth: np.ndarray, lens: Lens, near: float, rule: SliceRule = SLICE_RULE,
                share: bool = True) -> tuple[list[Layer], np.ndarray]:
    """The non-empty layers, front to back, of Gaussians at camera depths ``depth`` (N,) scene
    units in draw order, nearest first; those at z ≤ ``near`` (culled) are left out. ``share``:
    neighbour sharing (layers between slice centres), else disjoint slices. Returns the layers and
    (N,) float32 each Gaussian's share t of its layer's farther centre (0 where not shared). An
    order sorted for an earlier view (the viewer's background sort) is nearly sorted: each
    Gaussian takes the farthest layer of those before it, so the ranges stay contiguous."""
    live = depth > near
    c = signed_coc(depth[live], lens)
    slicing = assign_slices(c, rule)
    k = slicing.count
    t = np.zeros(len(depth), np.float32)
    group = slicing.index
    if share:  # intervals 0…k between the k centres; the huge layers become -1 and k + 1
        interval, t[live] = share_weights(c, 0.5 * (slicing.edges[:-1] + slicing.edges[1:]))
        group = np.where(slicing.index == -1, -1, np.where(slicing.index == k, k + 1, interval))
    last = k + 1 if share else k
    key = np.full(len(depth), -2, np.int64)  # -2: culled; -1 the front layer, then the slices, `last` the back layer
    key[live] = group
    key = np.maximum.accumulate(key) if key.size else key
    bounds = np.searchsorted(key, np.arange(-1, last + 2), side="left")
    layers = []
    for v in range(-1, last + 1):
        first, end = int(bounds[v + 1]), int(bounds[v + 2])
        if end <= first:
            continue
        if v in (-1, last):
            layers.append(Layer(first, end, 0.0, True))
        elif share:
            near_c, far_c = max(v - 1, 0), min(v, k - 1)
            layers.append(Layer(first, end, float(slicing.radius[near_c]), False,
                                float(slicing.radius[far_c]) if far_c != near_c else None))
        else:
            layers.append(Layer(first, end, float(slicing.radius[v]), False))
    return layers, t


def screen_boxes(scene, order: np.ndarray, camera: Camera, layers: list[Layer], near: float) -> list[tuple[int, int, int, int]]:
    """Per layer the pixels its pinhole blend can touch, (x0, y0, x1, y1) image pixels, rows from
    the top, ends exclusive, clipped to the frame: the union of its Gaussians' 3σ boxes, with σ
    bounded by the largest scale through the norm of the projection's Jacobian (the frustum clamp
    of project.glsl, ±15 % beyond the frame), the 0.3 px² low-pass and a pixel of margin. The blur
    and composite passes of a slice run only there (and its blur radius around it)."""
    w, h = camera.width, camera.height
    t = camera.world_to_camera(scene.means[order])
    z = np.maximum(t[:, 2], near)
    tx = np.clip(t[:, 0] / z, (-camera.cx - 0.15 * w) / camera.fx, (1.15 * w - camera.cx) / camera.fx)
    ty = np.clip(t[:, 1] / z, (-camera.cy - 0.15 * h) / camera.fy, (1.15 * h - camera.cy) / camera.fy)
    gain = max(camera.fx, camera.fy) / z * np.sqrt(1.0 + tx * tx + ty * ty)
    reach = 3.0 * np.sqrt((gain * scene.scales[order].max(axis=1)) ** 2 + 0.3) + 1.0
    u, v = camera.fx * t[:, 0] / z + camera.cx, camera.fy * t[:, 1] / z + camera.cy
    boxes = []
    for layer in layers:
        part = slice(layer.first, layer.end)
        if layer.lensed:  # blurred by the lens as drawn: anywhere
            boxes.append((0, 0, w, h))
            continue
        x0, y0 = (int(np.clip(np.floor(np.min(a[part] - reach[part])), 0, n)) for a, n in ((u, w), (v, h)))
        x1, y1 = (int(np.clip(np.ceil(np.max(a[part] + reach[part])) + 1, 0, n)) for a, n in ((u, w), (v, h)))
        boxes.append((x0, y0, x1, y1))
    return boxes


class GreyCore:
    """The scene's storage with every Gaussian's colour replaced by a grey level and no view
    terms (a zeroed SH-rest buffer): the buffers a shared layer's second blend reads."""

    def __init__(self, renderer) -> None:
        scene, ctx = renderer.scene, renderer.ctx
        self.packed, self.scale = renderer.packed, renderer.colour_scale
        self.core = pack_core(scene, self.scale) if self.packed else full_core(scene)
        self.buffers = {0: ctx.buffer(reserve=max(self.core.nbytes, 16))}
        if 2 in renderer._buffers:
            self.buffers[2] = ctx.buffer(reserve=renderer._buffers[2].size)
            self.buffers[2].clear()

    def write(self, grey: np.ndarray) -> None:
        """Set the colour of each Gaussian (scene order) to ``grey`` (N,) in [0, 1]."""
        core = self.core.copy()
        if self.packed:  # the colour's three halves: word 4's high half, word 5
            h = (grey / np.float32(self.scale)).astype(np.float16).view(np.uint16).astype(np.uint32)
            core[:, 4] = (core[:, 4] & 0xFFFF) | (h << 16)
            core[:, 5] = h | (h << 16)
        else:
            core[:, 11:14] = grey[:, None]
        if core.size:
            self.buffers[0].write(core.tobytes())

    def release(self) -> None:
        for buf in self.buffers.values():
            buf.release()


class SlicedDof:
    """The sliced mode of one :class:`~dofview.rendering.base.Renderer` (made by its first
    sliced draw; its targets follow the frame size)."""

    def __init__(self, renderer) -> None:
        self.r = renderer
        ctx = renderer.ctx
        self.ctx = ctx

        def program(frag: str) -> tuple[moderngl.Program, moderngl.VertexArray]:
            prog = ctx.program(vertex_shader=load_shader("fullscreen.vert"), fragment_shader=load_shader(frag))
            return prog, ctx.vertex_array(prog, [])

        self._down = program("slice_down.frag")
        self._blur = program("slice_blur.frag")
        self._composite = program("slice_composite.frag")
        self._resolve = program("slice_resolve.frag")
        self._taps = ctx.buffer(reserve=16)
        self._counted = ctx.buffer(reserve=4)  # the renderer's Gaussian counter, kept over a grey blend
        self._kernels: dict[tuple[float, int, float], np.ndarray] = {}
        self._size: tuple[int, int] | None = None
        self._key: tuple[int, int, int] | None = None  # size and the renderer's colour target
        self._levels: dict[int, tuple[moderngl.Texture, moderngl.Framebuffer, moderngl.Texture, moderngl.Framebuffer]] = {}
        self._grey: GreyCore | None = None  # made by the first draw with a shared layer
        self.layers: list[Layer] = []
        """The layers of the last draw (for tests and the benchmark)."""
        self.share = True
        """Neighbour sharing (False: disjoint slices, the variant tests and benchmarks compare)."""
        self.max_full_radius: float | None = None
        """Blur radius px above which a slice blurs at reduced resolution; None: by the aperture
        (:func:`full_radius_limit`; the benchmark varies it)."""

    # ---- targets -------------------------------------------------------------------------------
    def _texture(self, size: tuple[int, int]) -> moderngl.Texture:
        tex = self.ctx.texture(size, 4, dtype="f4")
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        return tex

    def _targets(self, width: int, height: int) -> None:
        """Camera-sized slice targets, and the framebuffers that write into the renderer's targets
        (made again with them)."""
        key = (width, height, self.r.colour_tex.glo)
        if self._key == key:
            return
        self._release_targets()
        size = (width, height)
        (self.slice_colour, self.slice_depth, self.blurred, self.over, self.visible, self.share_tex,
         self.sum) = (self._texture(size) for _ in range(7))
        fb = self.ctx.framebuffer
        self.slice_fbo = fb(color_attachments=[self.slice_colour, self.slice_depth])
        self.share_fbo = fb(color_attachments=[self.share_tex, self.blurred])  # blurred: scratch depth sums
        self.sum_fbo = fb(color_attachments=[self.sum])
        self.blurred_fbo = fb(color_attachments=[self.blurred])
        self.over_fbo = fb(color_attachments=[self.over, self.r.depth_tex])  # "over" and the depth sums
        self.visible_fbo = fb(color_attachments=[self.visible])
        self.colour_fbo = fb(color_attachments=[self.r.colour_tex])
        self._size, self._key = size, key

    def _level(self, scale: int) -> tuple[moderngl.Texture, moderngl.Framebuffer, moderngl.Texture, moderngl.Framebuffer]:
        """The (down, its framebuffer, blurred, its framebuffer) targets at 1/``scale`` resolution."""
        if scale not in self._levels:
            w, h = self._size
            size = (-(-w // scale), -(-h // scale))
            down, blurred = self._texture(size), self._texture(size)
            self._levels[scale] = (down, self.ctx.framebuffer(color_attachments=[down]), blurred,
                                   self.ctx.framebuffer(color_attachments=[blurred]))
        return self._levels[scale]

    @property
    def gpu_bytes(self) -> int:
        """Bytes of the slice targets as now allocated."""
        if self._size is None:
            return 0
        w, h = self._size
        return 7 * 16 * w * h + sum(2 * 16 * lv[0].width * lv[0].height for lv in self._levels.values())

    # ---- one frame -----------------------------------------------------------------------------
    def draw(self, camera: Camera, lens: Lens, settings: RenderSettings, count: bool) -> None:
        """The sliced image of the renderer's scene in its current order into its targets."""
        r = self.r
        self._targets(camera.width, camera.height)
        order = r.front_to_back()
        self.layers, share = plan_layers(camera_depths(r.scene.means[order], camera), lens, settings.near,
                                           share=self.share)
        boxes = screen_boxes(r.scene, order, camera, self.layers, settings.near)
        pinhole = (Lens(lens.focus, 0.0), replace(settings, tau=0.0, dof="splat"), count)
        lensed = (lens, replace(settings, dof="splat"), False)
        if any(layer.back_radius is not None for layer in self.layers):
            if self._grey is None:
                self._grey = GreyCore(r)
            grey = np.zeros(r.scene.count, np.float32)
            grey[order] = share
            self._grey.write(grey)
        for fbo in (self.over_fbo, self.visible_fbo):
            fbo.use()
            fbo.clear(0.0, 0.0, 0.0, 0.0)
        prepared = None
        for layer, box in zip(self.layers, boxes):
            setup = lensed if layer.lensed else pinhole
            if setup is not prepared:
                r._prepare(camera, *setup)
                prepared = setup
            r._splat_range(layer.first, layer.end, self.slice_fbo)
            if layer.back_radius is not None:
                if count:  # preparing again may count again (compute counts as it preprocesses)
                    self.ctx.copy_buffer(self._counted, r._counter)
                scene_buffers, r._buffers = r._buffers, self._grey.buffers
                r._prepare(camera, *pinhole[:2], False)
                r._splat_range(layer.first, layer.end, self.share_fbo)
                r._buffers = scene_buffers
                r._prepare(camera, *pinhole)
                if count:
                    self.ctx.copy_buffer(r._counter, self._counted)
            # the visible part first: it is weighted by the coverage in front, which the "over" pass adds to
            self._blur_and_add(layer, box, settings, self.visible_fbo, (moderngl.ONE, moderngl.ONE), True)
            self._blur_and_add(layer, box, settings, self.over_fbo, (moderngl.ONE_MINUS_DST_ALPHA, moderngl.ONE), False)
        prog, vao = self._resolve
        self._run(prog, vao, self.colour_fbo, {"u_over": 0, "u_visible": 1}, [self.over, self.visible],
                  (0, 0, camera.width, camera.height))

    def _kernel(self, radius: float, settings: RenderSettings) -> np.ndarray:
        """(T, 4) float32 taps (dx, dy, weight, 0) in GL texel offsets (y up) of the aperture of
        ``radius`` px: slices.aperture_kernel's, mirrored as its convolution gathers."""
        key = (radius, settings.blades, settings.blade_rotation)
        if key not in self._kernels:
            if len(self._kernels) > 256:  # the viewer's lens changes make new radii every frame
                self._kernels.clear()
            k = aperture_kernel(radius, settings.blades, math.radians(settings.blade_rotation))
            n = k.shape[0] // 2
            rows, cols = np.nonzero(k)
            # output(p) = Σ k[n + dy, n + dx] · image(p − (dx, dy)) with image rows downwards: in GL
            # texels (rows upwards) the offset is (−dx, +dy)
            taps = np.stack([-(cols - n), rows - n, k[rows, cols], np.zeros(len(rows))], 1)
            self._kernels[key] = np.ascontiguousarray(taps, np.float32)
        return self._kernels[key]

    def _blur_and_add(self, layer: Layer, box: tuple[int, int, int, int], settings: RenderSettings,
                      target: moderngl.Framebuffer, blend: tuple[int, int], masked: bool) -> None:
        """Blur the slice target by ``layer``'s radius (``masked``: its part visible through the
        pinhole coverage in front, held by the renderer's depth target) and blend it into
        ``target`` with ``blend`` (its second attachment, if any, takes the slice's depth sums), in
        ``box`` (image pixels, rows from the top) and as far around it as the blur reaches: outside,
        the slice is empty. A shared layer's two parts are blurred by their radii and summed first."""
        if layer.back_radius is None:
            colour, scale, reach = self._blur_part(layer.radius, box, settings, masked, 0)
            self._add(colour, scale, reach, box, target, blend, masked, 0)
            return
        x0, y0, x1, y1 = box
        grow = 2 * int(math.ceil(max(layer.radius, layer.back_radius))) + 4  # beyond what either part reaches
        self.sum_fbo.clear(0.0, 0.0, 0.0, 0.0, viewport=self._region((x0 - grow, y0 - grow, x1 + grow, y1 + grow), 1, 0))
        reach = 0
        for part, radius in ((1, layer.radius), (2, layer.back_radius)):
            colour, scale, part_reach = self._blur_part(radius, box, settings, masked, part)
            self._add(colour, scale, part_reach, box, self.sum_fbo, (moderngl.ONE, moderngl.ONE), masked, part)
            reach = max(reach, part_reach)
        self._add(self.sum, 1, reach, box, target, blend, False, 0)

    def _blur_part(self, radius: float, box: tuple[int, int, int, int], settings: RenderSettings, masked: bool,
              part: int) -> tuple[moderngl.Texture | None, int, int]:
        """The slice target (``masked``, ``part``: weighted as :meth:`_blur_and_add`'s and
        slice_share.glsl's) blurred by ``radius`` px: the texture (None below ½ px, where the slice
        is its own blur, weighted in the composite pass), its resolution reduction and how far
        beyond ``box`` it reaches, px."""
        if radius < 0.5:  # below, slices.blur_slice is the identity
            return None, 1, 0
        cover = self.r.depth_tex
        self.ctx.disable(moderngl.BLEND)
        scale = blur_scale(radius, self.max_full_radius or full_radius_limit(settings.blades))
        taps = self._kernel(radius / scale, settings)
        n = int(np.abs(taps[:, :2]).max())
        src, out_fbo = self.slice_colour, self.blurred_fbo
        if scale > 1:
            down, down_fbo, blurred, out_fbo = self._level(scale)
            prog, vao = self._down
            # the blur reads n blocks around what it writes, itself n + 2 blocks around the box
            self._run(prog, vao, down_fbo, {"u_src": 0, "u_cover": 1, "u_share": 2, "u_scale": scale,
                                            "u_masked": masked, "u_part": part},
                      [self.slice_colour, cover, self.share_tex], self._region(box, scale, 2 * n + 3))
            src = down
        if self._taps.size < taps.nbytes:
            self._taps.orphan(taps.nbytes)
        self._taps.write(taps.tobytes())
        self._taps.bind_to_storage_buffer(0)
        prog, vao = self._blur
        full = scale == 1
        self._run(prog, vao, out_fbo, {"u_src": 0, "u_cover": 1, "u_share": 2, "u_taps": len(taps),
                                       "u_masked": masked and full, "u_part": part if full else 0},
                  [src, cover, self.share_tex], self._region(box, scale, n + 2))
        return out_fbo.color_attachments[0], scale, (n + 1) * scale

    def _add(self, colour: moderngl.Texture | None, scale: int, reach: int, box: tuple[int, int, int, int],
             target: moderngl.Framebuffer, blend: tuple[int, int], masked: bool, part: int) -> None:
        """Blend ``colour`` (at 1/``scale`` resolution; None: the unblurred slice target, weighted
        as ``masked`` and ``part`` say) into ``target`` with ``blend``, over ``box`` grown by
        ``reach`` px."""
        ctx = self.ctx
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = blend
        ctx.blend_equation = moderngl.FUNC_ADD
        prog, vao = self._composite
        x0, y0, x1, y1 = box
        raw = colour is None
        self._run(prog, vao, target, {"u_colour": 0, "u_depth": 1, "u_cover": 2, "u_share": 3, "u_scale": scale,
                                      "u_masked": raw and masked, "u_part": part if raw else 0},
                  # the renderer's depth target is read only where it is not written (a feedback loop)
                  [colour or self.slice_colour, self.slice_depth, self.r.depth_tex if raw and masked else self.slice_depth,
                   self.share_tex],
                  self._region((x0 - reach, y0 - reach, x1 + reach, y1 + reach), 1, 0))
        ctx.disable(moderngl.BLEND)

    def _region(self, box: tuple[int, int, int, int], scale: int, grow: int) -> tuple[int, int, int, int]:
        """The scissor (x, y, w, h) in a 1/``scale`` target (GL rows, from the bottom) of the blocks
        covering ``box`` (image pixels, rows from the top) and ``grow`` blocks around them; the
        reduced targets' rows are flipped block rows (slice_down.frag), the full ones' plain rows."""
        fw, fh = self._size
        w, h = -(-fw // scale), -(-fh // scale)
        x0, y0, x1, y1 = box
        bx0, by0 = max(x0 // scale - grow, 0), max(y0 // scale - grow, 0)
        bx1, by1 = min(-(-x1 // scale) + grow, w), min(-(-y1 // scale) + grow, h)
        if bx1 <= bx0 or by1 <= by0:
            return (0, 0, 0, 0)
        return (bx0, h - by1, bx1 - bx0, by1 - by0)

    def _run(self, prog: moderngl.Program, vao: moderngl.VertexArray, fbo: moderngl.Framebuffer,
             uniforms: dict[str, int], textures: list[moderngl.Texture], scissor: tuple[int, int, int, int]) -> None:
        """One full-screen pass of ``prog`` into ``fbo`` reading ``textures`` at units 0, 1, …,
        limited to ``scissor`` (x, y, w, h)."""
        if scissor[2] <= 0 or scissor[3] <= 0:
            return
        for unit, tex in enumerate(textures):
            tex.use(unit)
        for name, value in uniforms.items():
            prog[name].value = value
        fbo.use()
        self.ctx.viewport = (0, 0, *fbo.size)
        self.ctx.scissor = scissor
        vao.render(moderngl.TRIANGLES, vertices=3)
        self.ctx.scissor = None

    def _release_targets(self) -> None:
        if self._size is not None:
            for obj in (self.slice_fbo, self.blurred_fbo, self.over_fbo, self.visible_fbo, self.colour_fbo,
                        self.share_fbo, self.sum_fbo, self.slice_colour, self.slice_depth, self.blurred, self.over,
                        self.visible, self.share_tex, self.sum):
                obj.release()
        for level in self._levels.values():
            for obj in level:
                obj.release()
        self._levels = {}
        self._size = self._key = None

    def release(self) -> None:
        """Free the slice targets and programs."""
        self._release_targets()
        self._taps.release()
        self._counted.release()
        if self._grey is not None:
            self._grey.release()
        for prog, vao in (self._down, self._blur, self._composite, self._resolve):
            vao.release()
            prog.release()
