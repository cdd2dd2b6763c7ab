#version 430
// Sliced depth of field, per layer: the tiles of its window (u_tiles) that its blend marked
// (tile_marks.TileMarks: only there can it hold light), listed for the passes at full resolution, and
// their marks cleared for the next layer. One thread a row of tiles: each run of marked tiles
// along it is listed as one rectangle (x0, y, x1) for the passes drawn over them (an instance a
// run, 4 vertices: slice_tiles.vert; a run, not a tile, an instance, since llvmpipe sets up every
// triangle at a cost), and each tile for those dispatched over them (a workgroup a tile, the 2D
// grid of dispatch.glsl: slice_visible.comp). The indirect draw (4, runs, 0, 0) and dispatch
// (x, y, 1, tiles) grow by atomics from (4, 0, 0, 0) and (0, 0, 1, 0). A layer covers a third to
// three quarters of its window's tiles in the shared scenes (docs/BENCHMARKS.md, "Cost in rooms").
layout(local_size_x = 64) in;

layout(std430, binding = MARKS_BINDING) buffer Marks { uint marks[]; };
layout(std430, binding = 4) writeonly buffer Tiles { uvec2 tiles[]; };
layout(std430, binding = 5) writeonly buffer Runs { uvec4 runs[]; };
layout(std430, binding = 6) buffer Commands { uvec4 draw; uvec4 dispatch; };
uniform ivec4 u_tiles;  // (tx0, ty0, tx1, ty1), ends exclusive
uniform int u_columns;  // tiles a row of the marks holds

const uint MAX_GROUPS = 65535u;

void main() {
    int y = u_tiles.y + int(gl_GlobalInvocationID.x);
    if (y >= u_tiles.w) return;
    int row = y * u_columns;
    for (int x = u_tiles.x; x < u_tiles.z; ++x) {
        if (marks[row + x] == 0u) continue;
        int x0 = x;
        for (; x < u_tiles.z && marks[row + x] != 0u; ++x) marks[row + x] = 0u;
        runs[atomicAdd(draw.y, 1u)] = uvec4(x0, y, x, 0);
        uint n = uint(x - x0);
        uint at = atomicAdd(dispatch.w, n);
        for (uint i = 0u; i < n; ++i) tiles[at + i] = uvec2(x0 + int(i), y);
        atomicMax(dispatch.x, min(at + n, MAX_GROUPS));
        atomicMax(dispatch.y, (at + n - 1u) / MAX_GROUPS + 1u);
    }
}
