#version 430
// The compute backend's deep image: one workgroup per TILE x TILE tile, one thread per pixel, each
// walking its tile's splats in depth order (the binned pairs tiles_blend.comp blends: the same
// alpha, clamp and cuts) into deep samples (deep_walk.glsl). Only the pixels of image rows
// [u_rows.x, u_rows.y) (from the top) take part, as pixel (row - u_rows.x) * width + column of the
// band's buffers; a pass walks at most u_take splats of a tile from the u_skip-th on (llvmpipe's
// loop limit). TILE is #defined.
layout(local_size_x = TILE, local_size_y = TILE) in;

#include "lens.glsl"
#include "splat_record.glsl"
#include "deep_walk.glsl"

layout(std430, binding = 0) readonly buffer Splats { Splat splats[]; };
layout(std430, binding = 1) readonly buffer TileVals { uint tile_vals[]; };
layout(std430, binding = 2) readonly buffer Ranges { uvec2 ranges[]; };
layout(std430, binding = 3) readonly buffer Order { uint order[]; };
uniform float u_tau;
uniform uint u_tiles_x;
uniform ivec2 u_size;    // image width, height
uniform ivec2 u_rows;    // the band, rows from the top, end exclusive
uniform uint u_tile_row0;  // the first tile row dispatched (GL rows, from the bottom)
uniform uint u_skip;
uniform uint u_take;

void main() {
    uvec2 tile = gl_WorkGroupID.xy + uvec2(0u, u_tile_row0);
    ivec2 px = ivec2(tile * uint(TILE) + gl_LocalInvocationID.xy);
    int row = u_size.y - 1 - px.y;
    if (px.x >= u_size.x || row < u_rows.x || row >= u_rows.y) return;
    uint p = uint((row - u_rows.x) * u_size.x + px.x);
    DeepState s = deep_begin(p);
    uvec2 range = ranges[tile.y * u_tiles_x + tile.x];
    uint first = min(range.y, range.x + u_skip);
    uint end = first + min(range.y - first, u_take);
    for (uint j = first; j < end && deep_live(s); ++j) {
        uint g = order[tile_vals[j]];
        vec4 a = splats[g].a;
        vec4 b = splats[g].b;
        float alpha = splat_alpha(vec2(px) + 0.5 - a.xy, a.zw, splat_axis2(a, b), b.z, u_tau, b.y);
        deep_step(s, p, alpha, splats[g].c.rgb, b.w);
    }
    deep_finish(s, p);
}
