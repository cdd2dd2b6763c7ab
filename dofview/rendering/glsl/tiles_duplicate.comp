#version 430
// Compute rasteriser, step 3: one (tile, Gaussian) pair per touched tile, written in depth order
// from the scanned counts; a stable sort by tile then leaves each tile's list front to back. The
// pair's value is the Gaussian's place in the depth order (its rank), so that a tile's list is
// sorted by rank and a blend can take any range of the order from it (tiles_blend.comp).
// Gaussians [u_first, u_first + u_n) of the depth order; offsets are relative to u_base. A pass
// writes pairs [u_skip, u_skip + u_take) of each Gaussian (llvmpipe ends an invocation's loops after
// 65535 iterations, and a splat may cover more tiles than that on a large image).
layout(local_size_x = 256) in;

#include "splat_record.glsl"
#include "tile_test.glsl"

layout(std430, binding = 0) readonly buffer Order { uint order[]; };
layout(std430, binding = 1) readonly buffer Rects { uvec2 rects[]; };
layout(std430, binding = 2) readonly buffer Offsets { uint offsets[]; };
layout(std430, binding = 3) writeonly buffer TileKeys { uint tile_keys[]; };
layout(std430, binding = 4) writeonly buffer TileVals { uint tile_vals[]; };
layout(std430, binding = 5) readonly buffer Splats { Splat splats[]; };
uniform uint u_first;
uniform uint u_n;
uniform uint u_base;
uniform uint u_tiles_x;
uniform uint u_skip;
uniform uint u_take;

#include "dispatch.glsl"

void main() {
    uint i = group_index() * 256u + gl_LocalInvocationID.x;
    if (i >= u_n) return;
    uint g = order[u_first + i];
    uvec2 r = rects[g];
    uint x0 = r.x & 0xffffu, y0 = r.x >> 16;
    uint w = (r.y & 0xffffu) - x0;
    uint count = w * ((r.y >> 16) - y0);
    uint at = offsets[u_first + i] - u_base;
    if (count > 1u && count <= TEST_MAX) {  // the tiles the ellipse reaches, as tiles_count.comp counted
        if (u_skip > 0u) return;  // all written by the first pass
        Splat s = splats[g];
        for (uint y = y0; y < (r.y >> 16); ++y) {
            for (uint x = x0; x < x0 + w; ++x) {
                if (splat_touches_tile(s, uvec2(x, y))) {
                    tile_keys[at] = y * u_tiles_x + x;
                    tile_vals[at] = u_first + i;
                    ++at;
                }
            }
        }
        return;
    }
    uint end = u_skip + min(count - min(count, u_skip), u_take);
    for (uint k = u_skip; k < end; ++k) {
        tile_keys[at + k] = (y0 + k / w) * u_tiles_x + x0 + k % w;
        tile_vals[at + k] = u_first + i;
    }
}
