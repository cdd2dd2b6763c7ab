#version 430
// Sliced depth of field, per layer, at its level, before its gather: for each 8 × 8 tile of the
// gather, the largest |ρ| of the prepared layer's texels with coverage within u_reach of it (the
// image's edge texels stand for what the gather repeats beyond it), or −1 where there is none, so
// that slice_gather.frag leaves such tiles at once and stops the others' taps where their sources'
// kernels end. Exact: a texel without coverage carries no colour (premultiplied) and no visible
// part. A layer is a thin depth range of the scene: most of its box is empty, and within it the
// blur changes little from one tile to the next. With u_mark (a reduced layer gathered into its
// run's accumulators), a tile with light marks the full-resolution tiles (tile_marks.TileMarks)
// that the run's upsampling reads it in: its block a texel wider on every side (bilinear).
layout(local_size_x = 8, local_size_y = 8) in;

layout(std430, binding = MARKS_BINDING) buffer Marks { uint marks[]; };
uniform bool u_mark;
uniform int u_scale;       // the level's
uniform int u_columns;     // the marks' tiles a row
uniform ivec4 u_frame;     // full-resolution pixels marked within (x0, y0, x1, y1), GL rows

layout(r32f, binding = 0) uniform writeonly image2D u_occupied;
layout(rgba32f, binding = 1) uniform readonly image2D u_a;  // the prepared layer: colour / N(ρ)
layout(rg32f, binding = 2) uniform readonly image2D u_b;    // and (ρ, visible / N(ρ))
uniform ivec4 u_tiles;   // (x0, y0, x1, y1) tiles, ends exclusive
uniform int u_reach;     // the taps' largest offset along an axis, texels

void main() {
    ivec2 t = u_tiles.xy + ivec2(gl_GlobalInvocationID.xy);
    if (t.x >= u_tiles.z || t.y >= u_tiles.w) return;
    ivec2 last = imageSize(u_a) - 1;
    ivec2 lo = clamp(t * 8 - u_reach, ivec2(0), last);
    ivec2 hi = clamp(t * 8 + 7 + u_reach, ivec2(0), last);
    float widest = -1.0;
    for (int y = lo.y; y <= hi.y; ++y) {
        for (int x = lo.x; x <= hi.x; ++x) {
            if (imageLoad(u_a, ivec2(x, y)).a > 0.0) widest = max(widest, abs(imageLoad(u_b, ivec2(x, y)).r));
        }
    }
    imageStore(u_occupied, t, vec4(widest));
    if (u_mark && widest >= 0.0) {
        ivec2 first = max((t * 8 - 1) * u_scale, u_frame.xy) / TILE;
        ivec2 end = (min((t * 8 + 9) * u_scale, u_frame.zw) + TILE - 1) / TILE;
        for (int y = first.y; y < end.y; ++y)
            for (int x = first.x; x < end.x; ++x) marks[y * u_columns + x] = 1u;
    }
}
