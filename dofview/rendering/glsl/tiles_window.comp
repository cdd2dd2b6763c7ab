#version 430
// Compute rasteriser, step 5a: the tiles of a window (u_tiles) holding splats of ranks
// [u_window.x, u_window.y), listed with their part of the tile's pairs, and the indirect dispatch
// of step 5 over them: one thread per tile here, where a blend workgroup per tile of the window
// cost llvmpipe ~1.5 µs even for a tile with nothing to blend (a layer of the sliced mode holds
// splats in only part of its window: docs/BENCHMARKS.md, "Cost in rooms", "Compute backend:
// blending only the tiles a range reaches"). The command (x, y, 1) spreads the list over a 2D
// grid (dispatch.glsl): x = min(count, MAX_GROUPS), y = ⌈count / MAX_GROUPS⌉, grown by atomicMax
// from (0, 0, 1, 0).
layout(local_size_x = 8, local_size_y = 8) in;

layout(std430, binding = 1) readonly buffer TileVals { uint tile_vals[]; };
layout(std430, binding = 2) readonly buffer Ranges { uvec2 ranges[]; };
layout(std430, binding = 5) writeonly buffer Listed { uvec4 listed[]; };  // (tile x, tile y, first pair, end)
layout(std430, binding = 6) buffer Command { uvec4 command; };  // (groups x, groups y, 1, tiles listed)
uniform uvec4 u_tiles;  // (tx0, ty0, tx1, ty1), ends exclusive
uniform uint u_tiles_x;
uniform uvec2 u_window;

// A listed tile marks the tiles of tile_marks.TileMarks (u_mark_size px) that share its pixels: the
// range may write there.
layout(std430, binding = MARKS_BINDING) buffer Marks { uint marks[]; };
uniform bool u_mark;
uniform uint u_mark_size;
uniform uint u_mark_columns;
uniform uvec4 u_mark_tiles;  // the box's tiles of the marks (tx0, ty0, tx1, ty1), ends exclusive

const uint MAX_GROUPS = 65535u;

// The first place in tile_vals[lo, hi) (ascending) holding a rank ≥ rank.
uint lower_bound(uint lo, uint hi, uint rank) {
    while (lo < hi) {
        uint mid = (lo + hi) / 2u;
        if (tile_vals[mid] < rank) lo = mid + 1u; else hi = mid;
    }
    return lo;
}

void main() {
    uvec2 tile = gl_GlobalInvocationID.xy + u_tiles.xy;
    if (any(greaterThanEqual(tile, u_tiles.zw))) return;
    uvec2 range = ranges[tile.y * u_tiles_x + tile.x];
    range.x = lower_bound(range.x, range.y, u_window.x);
    range.y = lower_bound(range.x, range.y, u_window.y);
    if (range.x == range.y) return;
    uint at = atomicAdd(command.w, 1u);
    listed[at] = uvec4(tile, range);
    atomicMax(command.x, min(at + 1u, MAX_GROUPS));
    atomicMax(command.y, at / MAX_GROUPS + 1u);
    if (u_mark) {
        uvec2 first = max(tile * TILE / u_mark_size, u_mark_tiles.xy);
        uvec2 end = min(((tile + 1u) * TILE + u_mark_size - 1u) / u_mark_size, u_mark_tiles.zw);
        for (uint y = first.y; y < end.y; ++y)
            for (uint x = first.x; x < end.x; ++x) marks[y * u_mark_columns + x] = 1u;
    }
}
