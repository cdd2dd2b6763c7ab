#version 430
// Compute rasteriser, step 4: each tile's [start, end) in the tile-sorted pair list (tiles not
// touched keep the cleared (0, 0)).
layout(local_size_x = 256) in;
layout(std430, binding = 0) readonly buffer TileKeys { uint tile_keys[]; };
layout(std430, binding = 1) buffer Ranges { uvec2 ranges[]; };
uniform uint u_n;

#include "dispatch.glsl"

void main() {
    uint i = group_index() * 256u + gl_LocalInvocationID.x;
    if (i >= u_n) return;
    uint k = tile_keys[i];
    if (i == 0u || tile_keys[i - 1u] != k) ranges[k].x = i;
    if (i + 1u == u_n || tile_keys[i + 1u] != k) ranges[k].y = i + 1u;
}
