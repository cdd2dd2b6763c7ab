"""The display pass every backend shares: scene statistics on the GPU and the tone-mapping pass.

One fragment program per operator (``tonemap.frag`` with the operator's ``tonemap_<name>.glsl``
as the OPERATOR define, compiled when first used); the histogram operator's curve (built per
exposure from the statistics' CDF, :meth:`~dofview.tonemap.histogram.Histogram.curve`) as a
(N + 1)×1 R32F texture; the bilateral operator's base layer as two R32F passes
(``bilateral.frag``). Statistics: ``stats_histogram.comp`` counts log2 histograms of the HDR frame
into a small buffer, and only that buffer is read back (32 KB), never the frame; the numbers are
those of :func:`dofview.tonemap.stats.frame_stats` on the read-back frame.
"""

from __future__ import annotations

import moderngl
import numpy as np

from dofview.rendering.gl import load_shader, set_uniforms
from dofview.tonemap import Tonemap
from dofview.tonemap.stats import (
    COVERED_ALPHA,
    STATS_BINS,
    STATS_RANGE,
    WARD_BINS,
    Stats,
    cdf_domain,
    stats_from_histograms,
    with_cdf,
)

_DEFINES = {"COVERED_ALPHA": repr(COVERED_ALPHA)}


class DisplayPass:
    """GPU objects of the display pass for one context (owned by a Renderer)."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self._programs: dict[str, tuple[moderngl.Program, moderngl.VertexArray]] = {}
        self._tables: dict[str, list[tuple[str, moderngl.Texture]]] = {}
        self._stats_program: moderngl.ComputeShader | None = None
        self._hist = ctx.buffer(reserve=max(4 * STATS_BINS, WARD_BINS) * 4)
        self._cdf = ctx.texture((WARD_BINS + 1, 1), 1, dtype="f4")
        self._cdf.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._base: list[tuple[moderngl.Texture, moderngl.Framebuffer]] = []
        self._base_size: tuple[int, int] | None = None
        self._base_key: tuple | None = None  # what the base layer was computed for

    def _program(self, glsl: str, frag: str = "tonemap.frag", generated=None) -> tuple[moderngl.Program, moderngl.VertexArray]:
        """The pass's program; ``generated``: (GLSL text for ``#include GENERATED``, lookup tables)
        of an operator whose shader is made at run time, its tables uploaded as textures."""
        key = f"{frag}:{glsl}"
        if key not in self._programs:
            src = load_shader(frag, {**_DEFINES, "OPERATOR": glsl} if glsl else _DEFINES)
            if generated is not None:
                src = src.replace("#include GENERATED", generated[0])
                self._tables[key] = [(t.sampler, self._table_texture(t)) for t in generated[1]]
            prog = self.ctx.program(vertex_shader=load_shader("fullscreen.vert"), fragment_shader=src)
            self._programs[key] = (prog, self.ctx.vertex_array(prog, []))
        return self._programs[key]

    def _table_texture(self, table) -> moderngl.Texture:
        tex = self.ctx.texture((table.width, table.height), table.components, table.values.tobytes(), dtype="f4")
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR) if table.linear else (moderngl.NEAREST, moderngl.NEAREST)
        tex.repeat_x = tex.repeat_y = False
        return tex

    # ---- statistics --------------------------------------------------------------------------
    def histograms(self, colour: moderngl.Texture, encoded: bool, lo: float, hi: float, bins: int,
                   channels: int) -> np.ndarray:
        """(channels, bins) int64 log2 histograms of the covered pixels of ``colour``, counted on
        the GPU (twin: tonemap.stats.log_histograms)."""
        if self._stats_program is None:
            self._stats_program = self.ctx.compute_shader(load_shader("stats_histogram.comp", _DEFINES))
        buf = self._hist
        buf.clear()
        p = self._stats_program
        colour.use(0)
        set_uniforms(p, {"u_colour": 0, "u_encoded": encoded, "u_lo": float(lo), "u_scale": float(bins / (hi - lo)),
                 "u_bins": bins, "u_channels": channels})
        buf.bind_to_storage_buffer(0)
        w, h = colour.size
        p.run((w + 15) // 16, (h + 15) // 16)
        self.ctx.memory_barrier()
        return np.frombuffer(buf.read(size=channels * bins * 4), np.uint32).reshape(channels, bins).astype(np.int64)

    def stats(self, colour: moderngl.Texture, encoded: bool, operator, domain: tuple[float, float] | None,
              display_referred: bool) -> Stats:
        """Statistics of the frame in ``colour`` for ``operator``; the histogram operator's CDF over
        ``domain`` (log2; None: the frame's own [lo, hi]); ``display_referred``: an sRGB-trained
        scene. Twin: tonemap.stats.frame_stats."""
        stats = stats_from_histograms(self.histograms(colour, encoded, *STATS_RANGE, STATS_BINS, 4), display_referred)
        if operator.needs_cdf:
            lo, hi = domain or cdf_domain(stats)
            stats = with_cdf(stats, self.histograms(colour, encoded, lo, hi, WARD_BINS, 1)[0], lo, hi)
        return stats

    # ---- the pass ----------------------------------------------------------------------------
    def _base_targets(self, size: tuple[int, int]) -> None:
        """The guide (RGBA32F) and the two filter passes' outputs (R32F)."""
        if self._base_size == size:
            return
        self._release_base()
        for components in (4, 1, 1):
            tex = self.ctx.texture(size, components, dtype="f4")
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._base.append((tex, self.ctx.framebuffer(color_attachments=[tex])))
        self._base_size = size

    def _input_uniforms(self, encoded: bool, tm: Tonemap) -> dict[str, object]:
        return {"u_colour": 0, "u_depth": 1, "u_encoded": encoded,
                "u_background": tuple(float(c) for c in tm.background), "u_exposure": float(tm.multiplier)}

    def _bilateral(self, colour: moderngl.Texture, depth: moderngl.Texture, encoded: bool, tm: Tonemap) -> None:
        """The base layer: the guide, then the two filter passes into ``self._base[2]``."""
        self._base_targets(colour.size)
        self.ctx.viewport = (0, 0, *colour.size)
        guide, vao = self._program("", "bilateral_guide.frag")
        colour.use(0)
        depth.use(1)
        set_uniforms(guide, self._input_uniforms(encoded, tm))
        self._base[0][1].use()
        vao.render(moderngl.TRIANGLES, vertices=3)
        prog, vao = self._program("", "bilateral.frag")
        self._base[0][0].use(0)
        set_uniforms(prog, {"u_guide": 0, "u_values": 1, **tm.operator.filter_uniforms(*colour.size)})
        for i, direction in enumerate(((1, 0), (0, 1))):
            if i:
                self._base[1][0].use(1)
            set_uniforms(prog, {"u_first": i == 0, "u_dir": direction})
            self._base[i + 1][1].use()
            vao.render(moderngl.TRIANGLES, vertices=3)

    def run(self, colour: moderngl.Texture, depth: moderngl.Texture, encoded: bool, target: moderngl.Framebuffer,
            viewport: tuple[int, int, int, int], tm: Tonemap, stats: Stats | None,
            extra: dict[str, object], same_frame: bool, display_referred: bool) -> None:
        """Tone map ``colour`` into ``target`` at ``viewport``. Adaptive operators need ``stats``
        (taken from this frame on the GPU when None, ``display_referred`` for an sRGB-trained
        scene); ``extra``: the focus-aid uniforms;
        ``same_frame``: ``colour`` is unchanged since the last call, so the bilateral base layer
        (the costly part) is kept when ``tm`` is too."""
        op = tm.operator
        if op.adaptive and stats is None:
            stats = self.stats(colour, encoded, op, None, display_referred)
        key = (tm, colour.size, encoded)
        if op.needs_base and not (same_frame and self._base_key == key):
            self._bilateral(colour, depth, encoded, tm)
            self._base_key = key
        prog, vao = self._program(op.glsl, generated=op.generated_glsl())
        for unit, (sampler, tex) in enumerate(self._tables.get(f"tonemap.frag:{op.glsl}", []), start=4):
            tex.use(unit)
            set_uniforms(prog, {sampler: unit})
        colour.use(0)
        depth.use(1)
        values = {**self._input_uniforms(encoded, tm), "u_gamma": float(tm.gamma), **extra,
                  **op.uniforms(stats, float(tm.multiplier))}
        if op.needs_cdf:
            self._cdf.write(np.asarray(op.curve(stats, float(tm.multiplier)), np.float32).tobytes())
            self._cdf.use(2)
            values["u_cdf"] = 2
        if op.needs_base:
            self._base[2][0].use(3)
            values["u_base"] = 3
        set_uniforms(prog, values)
        target.use()
        self.ctx.viewport = viewport
        vao.render(moderngl.TRIANGLES, vertices=3)

    def _release_base(self) -> None:
        for tex, fbo in self._base:
            fbo.release()
            tex.release()
        self._base.clear()
        self._base_size = self._base_key = None

    def release(self) -> None:
        for prog, vao in self._programs.values():
            vao.release()
            prog.release()
        self._programs.clear()
        for tables in self._tables.values():
            for _, tex in tables:
                tex.release()
        self._tables.clear()
        if self._stats_program is not None:
            self._stats_program.release()
        for obj in (self._hist, self._cdf):
            obj.release()
        self._release_base()
