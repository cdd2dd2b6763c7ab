"""The tiles a range blended by ``Renderer.splat_range`` may have written (rendering/base.py): the
sliced mode's passes at full resolution run only in them (rendering/sliced.py). The backends'
shaders mark them (quads.vert, tiles_window.comp) and glsl/slice_tiles.comp lists them."""

from __future__ import annotations

from dataclasses import dataclass

import moderngl


@dataclass(frozen=True)
class TileMarks:
    """Where a range blended by ``Renderer.splat_range`` may have written, per square tile of
    the target (the sliced mode processes a layer at full resolution only in the tiles marked).

    Attributes:
        buffer: one uint32 per tile, rows of ``columns`` tiles from the target's bottom (GL rows),
            bound to storage binding :data:`MARKS_BINDING` by the backend; the range sets 1 in
            every tile holding a pixel it may write within its box (more is allowed, none fewer)
            and leaves the others as they are.
        size: a tile's side, pixels.
        columns: tiles per row.
    """

    buffer: moderngl.Buffer
    size: int
    columns: int


MARKS_BINDING = 7
"""The storage binding of :class:`TileMarks` in the backends' shaders (quads.vert, tiles_window.comp)."""
