#version 430
// Compute rasteriser, step 3: one (tile, Gaussian) pair per touched tile, written in depth order
// from the scanned counts; a stable sort by tile then leaves each tile's list front to back.
// Gaussians [u_first, u_first + u_n) of the depth order; offsets are relative to u_base.
layout(local_size_x = 256) in;
layout(std430, binding = 0) readonly buffer Order { uint order[]; };
layout(std430, binding = 1) readonly buffer Rects { uvec2 rects[]; };
layout(std430, binding = 2) readonly buffer Offsets { uint offsets[]; };
layout(std430, binding = 3) writeonly buffer TileKeys { uint tile_keys[]; };
layout(std430, binding = 4) writeonly buffer TileVals { uint tile_vals[]; };
uniform uint u_first;
uniform uint u_n;
uniform uint u_base;
uniform uint u_tiles_x;

#include "dispatch.glsl"

void main() {
    uint i = group_index() * 256u + gl_LocalInvocationID.x;
    if (i >= u_n) return;
    uint g = order[u_first + i];
    uvec2 r = rects[g];
    uint at = offsets[u_first + i] - u_base;
    for (uint y = r.x >> 16; y < (r.y >> 16); ++y) {
        for (uint x = r.x & 0xffffu; x < (r.y & 0xffffu); ++x) {
            tile_keys[at] = y * u_tiles_x + x;
            tile_vals[at] = g;
            ++at;
        }
    }
}
